"""The work of ``python -m mjxskill.select`` (``mjxskill.cli.select``: the command, its flags
and what it does are described there): the fronts of the runs listed, a pick made and exported,
its episode rendered.

This module imports mujoco (through the run directory and the rendering), which reads
MUJOCO_GL once, when imported: ``select.main`` sets it (``default_gl``) before importing this
module, so that headless rendering finds EGL.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from mjxskill._files import is_regular
from mjxskill.engine.build import build_rollout
from mjxskill.errors import CommandError, RunError
from mjxskill.evaluation.racing import raced_pick
from mjxskill.evaluation.render import RenderUnavailable, render_content, render_world
from mjxskill.evaluation.selection import best_unvalidated, choose, export_document, export_outputs, write_export
from mjxskill.evaluation.validation import row_validation, validated_union
from mjxskill.runs.atomic_write import refuse_links_out
from mjxskill.runs.layout import runs_in
from mjxskill.runs.outputs import check_outputs
from mjxskill.runs.run_dir import PARETO, Run, concat_all
from mjxskill.runs.run_task import load_run_task
from mjxskill.training.report import front_table


def _fronts(path: Path):
    """([(ref, run, its config, its front)], whether ``path`` holds several runs) for the runs
    ``path`` holds (a run, a repeated run or an experiment: ``mjxskill.runs.layout``). Of several,
    those not trained yet are left out (an experiment in progress lists the runs done so far); a
    damaged file is refused as ever."""
    refs = runs_in(path)
    out = []
    for ref in refs:
        run = Run(ref.path)
        config = run.config()
        if len(refs) > 1 and (not is_regular(run.path / PARETO, RunError) or len(run.pareto(config)) == 0):
            continue
        out.append((ref, run, config, run.front(config)))
    if not out:  # none trained: what a single run says
        run = Run(refs[0].path)
        run.front(run.config())
    return out, len(refs) > 1


def _say_race_winners(fronts, several: bool) -> None:
    """The pick of each robust run listed: the winner of its race (mjxskill.evaluation.racing)."""
    for ref, sub, _, front in fronts:
        raced = raced_pick(sub.path, front)
        if raced is not None:
            k, won, worlds = raced
            where = f"{ref.kind} seed {ref.seed} " if several else ""
            print(f"{where}race winner (the run's pick): row {k}, success {won}/{worlds} in fresh worlds of the known "
                  f"start configurations (race.json); --pick {k if not several else _union_row(fronts, ref, k)} takes it")


def _union_row(fronts, ref, k: int) -> int:
    """The listed row (#) of row ``k`` of the run ``ref`` among ``fronts``."""
    before = 0
    for other, _, _, front in fronts:
        if other == ref:
            return before + k
        before += len(front)
    raise ValueError(ref)


def _say_what_decided(union, i: int, validated, other: int | None, owner) -> None:
    """What a pick by constraint rested on, where some solutions were validated: a validated
    pick beside an unvalidated solution that did better in training, or a pick by training
    success because no validated solution met the limits."""
    def name(j: int) -> str:
        ref, _, _, k = owner[j]
        return f"# {j} ({ref.kind} seed {ref.seed} row {k})"

    if math.isnan(validated[i]):
        print(f"no validated solution meets the limits: {name(i)} is picked by its training success "
              f"{union.success_rate[i]:.0%} alone (the few worlds of its batch)")
    elif other is not None and union.success_rate[other] > validated[i]:
        print(f"validated first: {name(i)} succeeded in {validated[i]:.0%} of its validation worlds; {name(other)} "
              f"reached {union.success_rate[other]:.0%} in training but was not validated (--pick {other} takes it)")


def _render(args: argparse.Namespace, run, config, params, root: Path, folder: Path, hint: str):
    """(``{name: content}`` of the rendered episode for the export, None) or (None, why it could not
    be rendered: RenderUnavailable). Everything it needs is checked before anything is computed
    (the run's task, ``--config-index``, no link or file where the frames go); nothing is written."""
    scn, task = load_run_task(run, config)
    n_known = len(scn.robot.start_configs)
    if args.config_index >= n_known:
        raise CommandError(f"--config-index {args.config_index}: the task has known start configurations 0-{n_known - 1}")
    name = "episode.mp4" if args.format == "mp4" else "frames"
    # no link, no file in a folder's place (other content is compared once rendered)
    check_outputs(root, {folder / name: b"" if args.format == "mp4" else {}}, replace=True, hint=hint, flag="--replace")
    rollout = build_rollout(scn, task, config.engine, worlds=1, episode_seconds=config.episode_seconds)
    try:
        world = render_world(rollout, args.config_index, args.seed)
        print(f"rendering from start configuration {args.config_index} ({config.engine} engine) ...", flush=True)
        return {name: render_content(rollout, params, world, args.format, *args.size)}, None
    except RenderUnavailable as err:
        return None, err
    finally:
        rollout.close()


def select(args: argparse.Namespace, prog: str) -> int:
    """The command once MUJOCO_GL is set (``mjxskill.cli.select.main``); ``prog`` names it in its warnings."""
    refuse_links_out(args.run)  # before anything in it is read
    fronts, several = _fronts(args.run)
    if args.min_success is not None and args.min_success > 1:
        raise CommandError(f"--min-success is a rate between 0 and 1, got {args.min_success}")
    _, run, config, _ = fronts[0]
    union = concat_all([f for *_, f in fronts], len(config.parameter_names), len(config.objective_names), config.pooled)
    seconds: list[float] = []  # the validation's mean times to success, for the tie-break between equal validations
    validated, worlds = validated_union(((run, front) for _, run, _, front in fronts),
                                        damaged=lambda message: print(f"{prog}: warning: {message}; "
                                                                      "listed without its validation", file=sys.stderr),
                                        seconds=seconds)
    owner = [(ref, sub, c, k) for ref, sub, c, f in fronts for k in range(len(f))]  # union row -> its run and row
    if several:
        print(f"Pareto fronts of the {len(fronts)} trained runs in {args.run} ({len(union)} solutions; # numbers them all, "
              f"'run' names the run and its row of pareto.csv):")
        labels = [f"{ref.kind} seed {ref.seed} row {k}" for ref, _, _, k in owner]
        table = front_table(config, union, validated).splitlines()
        width = max(len(label) for label in labels)
        print("\n".join([f"{'run'.ljust(width)}  {table[0]}", *(f"{label.ljust(width)}  {line}" for label, line in zip(labels, table[1:]))]))
    else:
        print(f"Pareto front of {run.path} ({len(union)} solutions):")
        print(front_table(config, union, validated))
    _say_race_winners(fronts, several)
    if validated is not None:
        # validated_union gives both arrays or neither
        print(f"validated: the success rate of the picks' contenders in fresh worlds ({' or '.join(map(str, sorted(set(worlds[worlds > 0]))))} per solution; "  # type: ignore[index, operator]
              "evaluation/validation.json); a pick by constraint takes a validated solution first")
    if args.pick is None and args.max_force is None and args.min_success is None:
        print("pick one with --pick K or a constraint (--max-force N, --min-success RATE)")
        return 0
    if args.pick is not None:
        if args.pick >= len(union):
            raise CommandError(f"--pick {args.pick}: the front{'s have' if several else ' has'} rows 0-{len(union) - 1}")
        i = args.pick
    else:
        i = choose(union, args.max_force, args.min_success, validated, seconds or None)
        if validated is not None:
            _say_what_decided(union, i, validated, best_unvalidated(union, args.max_force, args.min_success, validated), owner)
    ref, run, config, k = owner[i]
    front = fronts[[f[0] for f in fronts].index(ref)][3]
    folder = args.out or Path(args.run) / (f"selected-{ref.kind}-{ref.seed}-{k}" if several else f"selected-{k}")
    root = args.out or Path(args.run)  # what the export owns: nothing below it is written through a link
    doc = export_document(config, front, k, run.path, row_validation(validated, worlds, i))
    hint = "move it away, or write this pick elsewhere with --out FOLDER"
    check_outputs(root, export_outputs(doc, folder), replace=args.replace, hint=hint, flag="--replace")  # before anything is computed
    rendering, unavailable = (None, None) if args.no_render else _render(args, run, config, front.params[k], root, folder, hint)
    for path in write_export(doc, folder, root, rendering, replace=args.replace, hint=hint, flag="--replace"):
        content = (rendering or {}).get(path.name)
        print(f"wrote {path}" if not isinstance(content, dict) else f"wrote {len(content)} frames to {path}")
    print(f"chose Pareto solution {k}{f' of {run.path}' if several else ''}: "
          + ", ".join(f"{n} = {v['value']:.4g} {v['unit']}" for n, v in doc["parameters"].items())
          + ("" if validated is None or math.isnan(validated[i]) else f" (validated success {validated[i]:.0%})"))
    if unavailable is not None:
        print(f"{prog}: rendering skipped: {unavailable}", file=sys.stderr)
        return 1
    return 0


__all__ = ["select"]
