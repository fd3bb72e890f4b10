"""``python -m mjxskill.train TASK``: learn the free parameters of a planned task.

    python -m mjxskill.train push            # the paper's settings: 400 evaluations, 7 worlds
    python -m mjxskill.train peg --budget 200 --batch-size 8 --init 40 --worlds 7 --seed 3 --out runs/peg-3
    python -m mjxskill.train push --resume runs/push-0
    python -m mjxskill.train push --repeats 10 --out runs/push-x10

The flags over the scenario's defaults make the run's configuration (``config.yaml``); the
loop itself is ``mjxskill.training.loop.train``, which this command drives with a progress bar
(tqdm, with ETA, hypervolume and best success rate) or, with ``--quiet``, one line per batch.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from mjxskill import cli
from mjxskill.cli import args as cli_args
from mjxskill.engines import CHOICES, build_rollout, resolve_engine
from mjxskill.errors import CommandError
from mjxskill.training.loop import optimizer_config, rollout_evaluator, train
from mjxskill.training.run_dir import Evaluations, Run, RunConfig


class Progress:
    """A tqdm bar with ETA, evaluations, hypervolume and best success rate; or, quiet, one log
    line per batch."""

    def __init__(self, total: int, quiet: bool, label: str = ""):
        self.total, self.quiet, self.label = total, quiet, label
        self.bar = None
        self.t0 = time.monotonic()

    def _fields(self, ev: Evaluations, ref) -> dict:
        from mjxskill.gp import hypervolume

        hv = hypervolume(-ev.objectives, ref) if ref is not None and len(ev) else float("nan")
        best = float(np.max(ev.success_rate)) if len(ev) else float("nan")
        return {"hv": f"{hv:.4g}" if math.isfinite(hv) else "warm-up", "best_success": f"{best:.0%}" if len(ev) else "-"}

    def start(self, ev: Evaluations, ref) -> None:
        if self.quiet:
            return
        from tqdm import tqdm

        self.bar = tqdm(total=self.total, initial=len(ev), desc=self.label or "evaluations", unit="eval", file=sys.stderr, dynamic_ncols=True)
        self.bar.set_postfix(self._fields(ev, ref))

    def update(self, new: Evaluations, ev: Evaluations, ref) -> None:
        fields = self._fields(ev, ref)
        if self.bar is not None:
            self.bar.set_postfix(fields, refresh=False)
            self.bar.update(len(new))
        else:
            elapsed = time.monotonic() - self.t0
            print(f"{self.label}{len(ev)}/{self.total} evaluations, hypervolume {fields['hv']}, "
                  f"best success {fields['best_success']}, {elapsed:.0f} s", flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


# -- command line ---------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mjxskill.train",
        description="Learn the free skill parameters of a task (multi-objective Bayesian optimization in MJX).",
    )
    cli_args.add_task_argument(parser)
    parser.add_argument("--budget", type=cli_args.positive_int, help="evaluations (parameter sets) per run (default: the scenario's)")
    parser.add_argument("--batch-size", type=cli_args.positive_int, help="parameter sets per batch (default: the scenario's)")
    parser.add_argument("--init", type=cli_args.int_at_least(2), help="random warm-up evaluations (default: the scenario's)")
    parser.add_argument("--worlds", type=cli_args.positive_int, help="randomized worlds per parameter set (default: the scenario's)")
    parser.add_argument("--seed", type=cli_args.int_at_least(0), help="seed of the optimizer and the worlds (default: the scenario's)")
    parser.add_argument("--episode-seconds", type=cli_args.positive_float, help="episode length in s (default: the scenario's)")
    parser.add_argument("--goal", help="PDDL goal to plan instead of the scenario's")
    parser.add_argument("--repeats", type=cli_args.positive_int, help="independent runs with seeds seed..seed+N-1 (default 1)")
    parser.add_argument("--out", type=Path, help="run directory (default runs/<task>-<timestamp>)")
    parser.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue the run in RUN_DIR to its budget")
    parser.add_argument("--quiet", action="store_true", help="no progress bar: one log line per batch")
    parser.add_argument("--engine", choices=CHOICES, default=None,
                        help="physics engine: mjx (compiled MJX), native (native MuJoCo, one process per core) or auto "
                             "(MJX on a GPU/TPU, native on a CPU; the default); stored with the run")
    parser.add_argument("--optimizer-option", action="append", type=optimizer_option, metavar="KEY=VALUE", default=None,
                        help="a further mjxskill.gp.MOBOConfig setting, e.g. n_raw=256 (repeatable; stored with the run)")
    return parser


RUN_DEFINED = ("bounds", "n_objectives", "batch_size", "n_init", "seed")  # set by the run, not by options


def optimizer_option(text: str) -> tuple[str, int | float]:
    """``KEY=VALUE`` for a numeric MOBOConfig field (argparse type)."""
    import dataclasses

    from mjxskill.gp import MOBOConfig

    key, sep, value = text.partition("=")
    fields = [f.name for f in dataclasses.fields(MOBOConfig) if f.name not in RUN_DEFINED]
    if not sep or key not in fields:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE with KEY one of {', '.join(fields)}; got {text!r}")
    try:
        number = int(value)
    except ValueError:
        try:
            number = float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{key}: expected a number, got {value!r}") from None
    return key, number


SETTING_FLAGS = {"budget": "budget", "batch_size": "batch_size", "init": "n_init", "worlds": "worlds",
                 "seed": "seed", "episode_seconds": "episode_seconds", "goal": "goal", "repeats": "repeats"}


def resolve_config(args: argparse.Namespace, scn, task, engine: str) -> RunConfig:
    """The run configuration of a new run of ``task`` on ``engine``: flags over the scenario's
    defaults."""
    opt = scn.optimizer
    config = RunConfig(
        task=scn.name,
        # a scenario name stays a name; a YAML path is made absolute for evaluate/select
        scenario=args.task if Path(args.task).name == args.task and not args.task.endswith((".yaml", ".yml")) else str(Path(args.task).resolve()),
        goal=task.goal,
        parameter_names=tuple(task.parameter_names),
        parameter_units=tuple(task.parameter_units),
        bounds=(tuple(map(float, task.bounds[0])), tuple(map(float, task.bounds[1]))),
        objective_names=tuple(scn.objective_names),
        budget=args.budget if args.budget is not None else opt.budget,
        batch_size=args.batch_size if args.batch_size is not None else opt.batch_size,
        n_init=args.init if args.init is not None else opt.n_init,
        worlds=args.worlds if args.worlds is not None else scn.randomization.n_worlds,
        seed=args.seed if args.seed is not None else opt.seed,
        episode_seconds=float(args.episode_seconds if args.episode_seconds is not None else scn.episode_seconds),
        repeats=args.repeats or 1,
        optimizer_options=dict(args.optimizer_option or []),
        engine=engine,
    )
    try:
        optimizer_config(config)
    except ValueError as err:  # MOBOConfig names the bad setting
        raise CommandError(f"--optimizer-option: {err}") from None
    if config.n_init > config.budget:
        raise CommandError(f"--init {config.n_init} exceeds the budget of {config.budget} evaluations")
    if not config.parameter_names:
        raise CommandError(f"the plan for {config.goal!r} leaves no parameter to learn")
    return config


def _resumed_config(args: argparse.Namespace) -> RunConfig:
    run = Run(args.resume)
    config = run.config()
    if args.optimizer_option and dict(args.optimizer_option) != config.optimizer_options:
        raise CommandError(f"--resume continues {args.resume} with its own optimizer options {config.optimizer_options}; drop --optimizer-option")
    given = {flag: getattr(args, flag) for flag in SETTING_FLAGS if getattr(args, flag) is not None}
    conflicts = [f"--{flag.replace('_', '-')} {value} (the run has {getattr(config, SETTING_FLAGS[flag])})"
                 for flag, value in given.items() if value != getattr(config, SETTING_FLAGS[flag])]
    if conflicts:
        raise CommandError(f"--resume continues {args.resume} with its own settings; drop {', '.join(conflicts)}")
    if args.engine not in (None, "auto", config.engine):
        raise CommandError(f"--resume continues {args.resume} on its own engine {config.engine!r}; drop --engine {args.engine}")
    if args.out is not None and Path(args.out).resolve() != Path(args.resume).resolve():
        raise CommandError("--out and --resume name different directories; --resume writes into its own")
    return config


def _main(args: argparse.Namespace) -> int:
    from mjxskill.task import describe, planning_texts
    from mjxskill.training.run_task import load_run_task, scenario_and_task

    if args.resume is not None:
        config = _resumed_config(args)
        run = Run(args.resume)
        scn, task = load_run_task(run, config, scenario=args.task)
    else:
        scn, task = scenario_and_task(args.task, args.goal)
        engine, why = resolve_engine(args.engine or "auto")
        config = resolve_config(args, scn, task, engine)
        out = args.out or Path("runs") / f"{scn.name}-{time.strftime('%Y%m%d-%H%M%S')}"
        run = Run(out)
        run.create(config, scn.source, planning_texts(task))
        if config.repeats > 1:
            for sub in run.sub_runs(config):
                sub.create(config.sub_run(int(sub.path.name.split("-")[1])), scn.source, planning_texts(task))

    print(describe(scn, task))
    print(f"objectives (larger is better): {', '.join(config.objective_names)}")
    print(f"budget {config.budget} evaluations, batches of {config.batch_size}, {config.n_init} random warm-up, "
          f"{config.worlds} worlds, {config.episode_seconds:g} s episodes, seed {config.seed}"
          + (f", {config.repeats} repeats" if config.repeats > 1 else ""))
    print(f"run directory: {run.path}", flush=True)
    if args.resume is not None:
        why = "the run's own"
    print(f"engine: {config.engine} ({why})", flush=True)

    from mjxskill.training import report

    rollout = build_rollout(scn, task, config.engine, worlds=config.worlds, episode_seconds=config.episode_seconds)
    started = time.monotonic()
    runs = run.sub_runs(config) if config.repeats > 1 else [run]
    try:
        for sub in runs:
            sub_config = sub.config()
            label = f"seed {sub_config.seed}: " if config.repeats > 1 else ""
            evaluate = rollout_evaluator(rollout, sub_config.batch_size, sub_config.seed)
            ev = train(sub, sub_config, evaluate, progress=Progress(sub_config.budget, args.quiet, label))
            report.write_run_figures(sub, sub_config, ev)
            print(report.summary(sub, sub_config, ev), flush=True)
    except KeyboardInterrupt:
        try:  # figures of what is done; the CSV already holds every finished batch
            report.write_run_figures(sub, sub_config, sub.evaluations(sub_config))
        except Exception:  # noqa: BLE001  (a second Ctrl-C or a plotting problem must not hide the message)
            pass
        print(f"\ninterrupted: every finished batch is in {run.path}; continue with "
              f"python -m mjxskill.train {args.task} --resume {run.path}", file=sys.stderr)
        return 130
    finally:
        getattr(rollout, "close", lambda: None)()  # the native engine's worker processes
    if config.repeats > 1:
        print(report.write_repeats(run, config, runs), flush=True)
    print(f"done in {time.monotonic() - started:.0f} s; results in {run.path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)

