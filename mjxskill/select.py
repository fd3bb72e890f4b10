"""``python -m mjxskill.select RUN_DIR``: pick a Pareto solution, export it, render it.

    python -m mjxskill.select runs/push-0                    # list the Pareto front
    python -m mjxskill.select runs/push-0 --pick 2           # row 2 of pareto.csv
    python -m mjxskill.select runs/push-0 --max-force 20     # the most successful under 20 N
    python -m mjxskill.select runs/push-0 --pick 2 --format mp4 --config-index 1

A pick by constraint keeps the Pareto solutions within every given limit (``--max-force``: the
largest feed-forward force the skills commanded in an episode, N, mean over the worlds; ``--min-success``) and takes the
one with the highest success rate, ties broken by the first objective. The choice is written to
``RUN_DIR/selected-<k>/parameters.yaml`` and ``parameters.json`` (parameter name -> value and
unit, ready for a controller) and rendered there (PNG frames, or an MP4 with ffmpeg).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Sequence

import numpy as np

from mjxskill import cli


def choose(front, max_force: float | None = None, min_success: float | None = None) -> int:
    """Row of ``front`` (Evaluations) meeting the limits with the best success rate, ties by
    the first objective. Raises CommandError when no row meets them."""
    ok = np.ones(len(front), bool)
    if max_force is not None:
        ok &= front.max_force <= max_force
    if min_success is not None:
        ok &= front.success_rate >= min_success
    if not ok.any():
        raise cli.CommandError(
            f"no Pareto solution meets the limits (max force {max_force}, min success {min_success}); the front's "
            f"peak forces span {front.max_force.min():.1f}-{front.max_force.max():.1f} N and its success rates "
            f"{front.success_rate.min():.0%}-{front.success_rate.max():.0%}"
        )
    rows = np.flatnonzero(ok)
    order = np.lexsort((-front.objectives[rows, 0], -front.success_rate[rows]))
    return int(rows[order[0]])


def export_document(config, front, k: int, run_path: Path) -> dict:
    """The chosen solution as plain data (YAML/JSON)."""
    return {
        "task": config.task,
        "goal": config.goal,
        "run": str(run_path),
        "pareto_index": k,
        "parameters": {
            name: {"value": float(v), "unit": unit}
            for name, v, unit in zip(config.parameter_names, front.params[k], config.parameter_units)
        },
        "objectives": {name: float(v) for name, v in zip(config.objective_names, front.objectives[k])},
        "success_rate": float(front.success_rate[k]),
        "max_force_N": float(front.max_force[k]),
        "evaluated_in": f"{config.worlds} randomized worlds, {config.episode_seconds:g} s episodes",
    }


def write_export(doc: dict, folder: Path) -> list[Path]:
    import yaml

    try:
        folder.mkdir(parents=True, exist_ok=True)
        paths = [folder / "parameters.yaml", folder / "parameters.json"]
        paths[0].write_text(yaml.safe_dump(doc, sort_keys=False))
        paths[1].write_text(json.dumps(doc, indent=2) + "\n")
    except OSError as err:
        raise cli.CommandError(f"cannot write the export to {str(folder)!r}: {err.strerror}") from None
    return paths


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.select", description="Pick a Pareto solution, export its parameters and render it.")
    parser.add_argument("run", type=Path, help="run directory written by mjxskill.train")
    pick = parser.add_argument_group("choice (none: list the front)")
    pick.add_argument("--pick", type=cli.int_at_least(0), metavar="K", help="row K of pareto.csv")
    pick.add_argument("--max-force", type=cli.nonnegative_float, metavar="N", help="largest commanded force (mean over worlds) at most N newtons")
    pick.add_argument("--min-success", type=cli.nonnegative_float, metavar="RATE", help="success rate at least RATE (0-1)")
    parser.add_argument("--out", type=Path, help="export folder (default RUN_DIR/selected-<K>)")
    parser.add_argument("--no-render", action="store_true", help="export the parameters only")
    parser.add_argument("--format", choices=("png", "mp4"), default="png", help="PNG frames (default) or an MP4 (needs ffmpeg)")
    parser.add_argument("--config-index", type=cli.int_at_least(0), default=0, help="known start configuration to render from (default 0)")
    parser.add_argument("--seed", type=cli.int_at_least(0), default=0, help="seed of the rendered world's randomization")
    parser.add_argument("--size", type=cli.positive_int, nargs=2, default=(640, 480), metavar=("W", "H"), help="frame size in pixels")
    return parser


def _main(args: argparse.Namespace) -> int:
    from mjxskill.render import default_gl

    default_gl()  # before anything imports mujoco
    from mjxskill.report import front_table
    from mjxskill.run_dir import Run

    run = Run(args.run)
    config = run.config()
    if config.repeats > 1:
        raise cli.CommandError(f"{run.path} holds {config.repeats} repeated runs; select from one of them, e.g. {run.sub_runs(config)[0].path}")
    front = run.pareto(config)
    if len(front) == 0:
        raise cli.CommandError(f"{run.path} has an empty Pareto front (no evaluations yet)")
    if args.min_success is not None and args.min_success > 1:
        raise cli.CommandError(f"--min-success is a rate between 0 and 1, got {args.min_success}")
    print(f"Pareto front of {run.path} ({len(front)} solutions):")
    print(front_table(config, front))
    if args.pick is None and args.max_force is None and args.min_success is None:
        print("pick one with --pick K or a constraint (--max-force N, --min-success RATE)")
        return 0
    if args.pick is not None:
        if args.pick >= len(front):
            raise cli.CommandError(f"--pick {args.pick}: the front has rows 0-{len(front) - 1}")
        k = args.pick
    else:
        k = choose(front, args.max_force, args.min_success)
    folder = args.out or run.path / f"selected-{k}"
    doc = export_document(config, front, k, run.path)
    for path in write_export(doc, folder):
        print(f"wrote {path}")
    print(f"chose Pareto solution {k}: " + ", ".join(f"{n} = {v['value']:.4g} {v['unit']}" for n, v in doc["parameters"].items()))
    if args.no_render:
        return 0

    from mjxskill.evaluate import load_run_scenario
    from mjxskill.render import RenderUnavailable, render_episode
    from mjxskill.rollout import compile_rollout

    scn = load_run_scenario(run, config)
    n_known = len(scn.robot.start_configs)
    if args.config_index >= n_known:
        raise cli.CommandError(f"--config-index {args.config_index}: the task has known start configurations 0-{n_known - 1}")
    import jax

    rollout = compile_rollout(scn, worlds=1, episode_seconds=config.episode_seconds)
    worlds = rollout.worlds_per_config(jax.random.PRNGKey(args.seed), 1)
    world = jax.tree.map(lambda x: x[args.config_index], worlds)
    print(f"rendering from start configuration {args.config_index} (compiles the episode trace once) ...", flush=True)
    try:
        paths = render_episode(rollout, front.params[k], world, folder / ("episode" if args.format == "mp4" else "frames"),
                               args.format, *args.size)
    except RenderUnavailable as err:
        print(f"{build_parser().prog}: rendering skipped: {err}", file=__import__("sys").stderr)
        return 1
    print(f"wrote {paths[0]}" if len(paths) == 1 else f"wrote {len(paths)} frames to {paths[0].parent}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
