"""``python -m mjxskill.train TASK``: learn the free parameters of a planned task.

    python -m mjxskill.train push            # the paper's settings: 400 evaluations, 7 worlds
    python -m mjxskill.train peg --budget 200 --batch-size 8 --init 40 --worlds 7 --seed 3 --out runs/peg-3
    python -m mjxskill.train push --resume runs/push-0
    python -m mjxskill.train push --repeats 10 --out runs/push-x10
    python -m mjxskill.train push --optimizer random --out runs/push-random   # the random-search baseline
    python -m mjxskill.train push --prior-from runs/push-0 --budget 100   # guided by an earlier run's front

The flags over the scenario's defaults make the run's configuration (``config.yaml``); the
loop itself is ``mjxskill.training.loop.train``, which this command drives with a progress bar
(tqdm, with ETA, hypervolume and best success rate) or, with ``--quiet``, one line per batch.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from mjxskill import cli
from mjxskill.cli import args as cli_args
from mjxskill.engine.build import build_rollout, resolve_engine
from mjxskill.errors import CommandError
from mjxskill.training.loop import rollout_evaluator, train
from mjxskill.training.priors import describe_prior, prior_from_run, scenario_prior
from mjxskill.runs.run_config import optimizer_problem
from mjxskill.runs.run_dir import Evaluations, Run, RunConfig
from mjxskill.runs.settings import BY_NAME, SETTINGS, cross_problems, optimizer_option_value


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
    add_setting_arguments(parser)
    parser.add_argument("--out", type=Path, help="run directory (default runs/<task>-<timestamp>)")
    parser.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue the run in RUN_DIR to its budget")
    parser.add_argument("--prior-from", type=Path, metavar="RUN_DIR", dest="prior_from",
                        help="guide the search by a prior built from the Pareto solutions of the earlier run in RUN_DIR "
                             "(same learnable parameters; overrides the scenario's parameter_priors; stored with the run)")
    return parser


def add_setting_arguments(parser: argparse.ArgumentParser, skip: tuple[str, ...] = (), defaults: dict | None = None) -> None:
    """One flag per run setting but ``skip`` (the same checks as config.yaml's,
    mjxskill.runs.settings; ``defaults``: name -> the default's text for the help), and
    --quiet and --optimizer-option: the flags of every command that trains."""
    for setting in SETTINGS:
        if setting.name in skip:
            parser.set_defaults(**{setting.name: None})
            continue
        default = (defaults or {}).get(setting.name) or setting.default_text or (
            "the scenario's" if setting.scenario is not None else setting.default)
        parser.add_argument(setting.flag, dest=setting.name, type=cli_args.setting_type(setting),
                            help=f"{setting.help} (default: {default})")
    parser.add_argument("--quiet", action="store_true", help="no progress bar: one log line per batch")
    parser.add_argument("--optimizer-option", action="append", type=optimizer_option, metavar="KEY=VALUE", default=None,
                        help="an acquisition setting of mjxskill.gp (AcquisitionSettings), e.g. n_raw=256 or "
                             "model=scalarized (repeatable; stored with the run)")


def optimizer_option(text: str) -> tuple[str, int | float | str]:
    """``KEY=VALUE`` for an acquisition setting of mjxskill.gp (argparse type), VALUE typed and
    checked by gp (a number or one of the setting's choices). What several options must satisfy
    together is checked in ``resolve_config``."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        return key, optimizer_option_value(key, value)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _origin(args: argparse.Namespace, name: str, value) -> str:
    """Where a setting's value came from, for a message: its flag, or the scenario."""
    setting = BY_NAME[name]
    return f"{setting.flag} {value}" if getattr(args, name) is not None else f"{name} {value} (the scenario's default)"


def resolve_config(args: argparse.Namespace, scn, task) -> RunConfig:
    """The run configuration of a new run of ``task``: flags over the scenario's defaults."""
    values = {s.name: getattr(args, s.name) if getattr(args, s.name) is not None else s.default_for(scn) for s in SETTINGS}
    values["goal"] = task.goal
    values["engine"] = resolve_engine(values["engine"])[0]
    for name, problem in cross_problems(values):
        raise CommandError(f"{_origin(args, name, values[name])} {problem}")
    config = RunConfig(
        task=scn.name,
        # a scenario name stays a name; a YAML path is made absolute for evaluate/select
        scenario=args.task if Path(args.task).name == args.task and not args.task.endswith((".yaml", ".yml")) else str(Path(args.task).resolve()),
        parameter_names=tuple(task.parameter_names),
        parameter_units=tuple(task.parameter_units),
        bounds=(tuple(map(float, task.bounds[0])), tuple(map(float, task.bounds[1]))),
        objective_names=tuple(scn.objective_names),
        optimizer_options=dict(args.optimizer_option or []),
        prior=run_prior(args, scn, task),
        **values,
    )
    if not config.parameter_names:
        raise CommandError(f"the plan for {config.goal!r} leaves no parameter to learn")
    problem = optimizer_problem(config)  # the run's own settings are checked: an option is left
    if problem:
        raise CommandError(f"--optimizer-option: {problem}" if args.optimizer_option else f"the optimizer refuses this run: {problem}")
    return config


def run_prior(args: argparse.Namespace, scn, task) -> dict | None:
    """The prior of a new run: ``--prior-from``'s (over the scenario's) or the scenario's."""
    own = scenario_prior(scn, task)
    if getattr(args, "prior_from", None) is None:
        return own
    prior = prior_from_run(args.prior_from, task.parameter_names, task.bounds)
    if own is not None:
        prior["source"] += "; overrides the scenario's parameter_priors"
    return prior


def resumed_config(args: argparse.Namespace, run_path: Path | None = None) -> RunConfig:
    """The configuration of the run ``--resume`` names (or ``run_path``, a run inside it),
    refusing flags that would change it."""
    run = Run(run_path or args.resume)
    config = run.config()
    if args.optimizer_option and dict(args.optimizer_option) != config.optimizer_options:
        raise CommandError(f"--resume continues {args.resume} with its own optimizer options {config.optimizer_options}; drop --optimizer-option")
    conflicts = [f"{s.flag} {getattr(args, s.name)} (the run has {getattr(config, s.name)})" for s in SETTINGS
                 if getattr(args, s.name) is not None and getattr(args, s.name) != getattr(config, s.name)]
    if conflicts:
        raise CommandError(f"--resume continues {args.resume} with its own settings; drop {', '.join(conflicts)}")
    if getattr(args, "prior_from", None) is not None:
        given = prior_from_run(args.prior_from, config.parameter_names, config.bounds)
        stored = None if config.prior is None else {k: v for k, v in config.prior.items() if k != "source"}
        if stored != {k: v for k, v in given.items() if k != "source"}:
            raise CommandError(f"--resume continues {args.resume} with the prior it started with "
                               f"({describe_prior(config.prior)}); drop --prior-from {args.prior_from}")
    if args.out is not None and Path(args.out).resolve() != Path(args.resume).resolve():
        raise CommandError("--out and --resume name different directories; --resume writes into its own")
    return config


def _main(args: argparse.Namespace) -> int:
    from mjxskill.task import planning_texts
    from mjxskill.runs.run_task import load_run_task, scenario_and_task

    if args.resume is not None:
        config = resumed_config(args)
        run = Run(args.resume)
        lock = run.lock()  # before anything is read for resuming: one writer per run
        with lock:
            run.check(config)
            scn, task = load_run_task(run, config, scenario=args.task)
            return _train(args, run, config, scn, task)
    scn, task = scenario_and_task(args.task, args.goal)
    config = resolve_config(args, scn, task)
    run = Run(args.out or Path("runs") / f"{scn.name}-{time.strftime('%Y%m%d-%H%M%S')}")
    run.create(config, scn.source, planning_texts(task))
    with run.lock():
        return _train(args, run, config, scn, task)


def _train(args: argparse.Namespace, run: Run, config: RunConfig, scn, task) -> int:
    from mjxskill.task import describe

    print(describe(scn, task))
    print(f"objectives (larger is better): {', '.join(config.objective_names)}")
    print(f"budget {config.budget} evaluations, batches of {config.batch_size}, {config.n_init} random warm-up, "
          f"{config.worlds} worlds, {config.episode_seconds:g} s episodes, seed {config.seed}"
          + (f", {config.repeats} repeats" if config.repeats > 1 else "")
          + (", uniform random search after the warm-up" if config.optimizer == "random" else ""))
    print(describe_prior(config.prior) + (" (the run's own)" if args.resume is not None and config.prior else ""))
    print(f"run directory: {run.path}", flush=True)
    why = "the run's own" if args.resume is not None else resolve_engine(args.engine or "auto")[1]
    print(f"engine: {config.engine} ({why})", flush=True)
    cli.interrupt.set_message(f"interrupted: every finished batch is in {run.path}; continue with "
                              f"python -m mjxskill.train {args.task} --resume {run.path}")
    runs = run.sub_runs(config) if config.repeats > 1 else [run]
    sub, sub_config = run, config
    try:
        from mjxskill.training import report

        rollout = build_rollout(scn, task, resolve_engine(config.engine)[0], worlds=config.worlds,
                                episode_seconds=config.episode_seconds)
        started = time.monotonic()
        for sub in runs:
            with sub.lock() if sub is not run else contextlib.nullcontext():
                sub_config = sub.config()
                label = f"seed {sub_config.seed}: " if config.repeats > 1 else ""
                evaluate = rollout_evaluator(rollout, sub_config.batch_size, sub_config.seed)
                ev = train(sub, sub_config, evaluate, progress=Progress(sub_config.budget, args.quiet, label))
                report.write_run_figures(sub, sub_config, ev)
                print(report.summary(sub, sub_config, ev), flush=True)
    except KeyboardInterrupt:
        from mjxskill.training import report

        # figures of what is done; the CSV already holds every finished batch
        return cli.interrupt.stopped("mjxskill.train", lambda: report.write_run_figures(sub, sub_config, sub.evaluations(sub_config)))
    finally:
        if "rollout" in locals():
            getattr(rollout, "close", lambda: None)()  # the native engine's worker processes
    if config.repeats > 1:
        print(report.write_repeats(run, config, runs), flush=True)
    print(f"done in {time.monotonic() - started:.0f} s; results in {run.path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)
