"""``python -m mjxskill.train TASK``: learn the free parameters of a planned task.

    python -m mjxskill.train push            # the paper's settings: 400 evaluations, 7 worlds
    python -m mjxskill.train peg --budget 200 --batch-size 8 --init 40 --worlds 7 --seed 3 --out runs/peg-3
    python -m mjxskill.train push --resume runs/push-0
    python -m mjxskill.train push --repeats 10 --out runs/push-x10
    python -m mjxskill.train push --optimizer random --out runs/push-random   # the random-search baseline
    python -m mjxskill.train push --optimizer optuna-tpe --out runs/push-tpe  # Optuna's sampler, to compare
    python -m mjxskill.train push --prior-from runs/push-0 --budget 100   # guided by an earlier run's front

The flags (``mjxskill.cli.run_settings``) over the scenario's defaults make the run's
configuration (``config.yaml``, ``mjxskill.training.configure``); the loop itself is
``mjxskill.training.loop.train``, which this command drives with a progress bar (tqdm, with
ETA, hypervolume and best success rate) or, with ``--quiet``, one line per batch
(``mjxskill.cli.progress``).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import time
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from mjxskill import cli
from mjxskill.cli import args as cli_args
from mjxskill.cli.progress import Progress
from mjxskill.cli.run_settings import (accept_scenario, add_accept_scenario_change, add_setting_arguments, new_config,
                                        resumed_config)
from mjxskill.engine.build import build_rollout, connect_cluster
from mjxskill.evaluation import racing
from mjxskill.runs.training_protocol import race_episodes
from mjxskill.task import describe, planning_texts
from mjxskill.training import report
from mjxskill.training.loop import rollout_evaluator, train
from mjxskill.training.priors import describe_prior
from mjxskill.runs.atomic_write import refuse_links_out
from mjxskill.runs.run_dir import Run, RunConfig
from mjxskill.runs.run_task import load_run_task, scenario_and_task

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.native.ray_pool import ClusterInfo
    from mjxskill.scenario.schema import Scenario
    from mjxskill.task import PlannedTask


# what proposes the batches after the warm-up, when it is not the Bayesian optimizer
AFTER_WARM_UP = {"random": ", uniform random search after the warm-up",
                 "optuna-nsga2": ", Optuna's NSGAIISampler after the warm-up",
                 "optuna-tpe": ", Optuna's TPESampler (multivariate) after the warm-up",
                 "optuna-gp": ", Optuna's GPSampler after the warm-up",
                 "botorch-qlognehvi": ", BoTorch's qLogNEHVI after the warm-up"}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mjxskill.train",
        description="Learn the free skill parameters of a task (multi-objective Bayesian optimization over "
                    "simulated episodes, on native MuJoCo or MJX).",
    )
    cli_args.add_task_argument(parser)
    add_setting_arguments(parser)
    cli_args.add_workers_argument(parser)
    cli_args.add_cluster_argument(parser)
    parser.add_argument("--out", type=Path, help="run directory (default runs/<task>-<timestamp>)")
    parser.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue the run in RUN_DIR to its budget")
    parser.add_argument("--prior-from", type=Path, metavar="RUN_DIR", dest="prior_from",
                        help="guide the search by a prior built from the Pareto solutions of the earlier run in RUN_DIR "
                             "(same learnable parameters; overrides the scenario's parameter_priors; stored with the run)")
    add_accept_scenario_change(parser)
    return parser


def _main(args: argparse.Namespace) -> int:
    for folder in (args.resume, args.prior_from):
        if folder is not None:
            refuse_links_out(folder)  # before anything in it is read
    if args.resume is not None:
        config = resumed_config(args)
        cluster = connect_cluster(args.ray_address, config.engine)
        run = Run(args.resume)
        lock = run.lock()  # before anything is read for resuming: one writer per run
        with lock:
            run.check(config)
            scn, task = load_run_task(run, config, scenario=args.task)
            if accept_scenario(args, run, scn):
                config = run.config()
            return _train(args, run, config, scn, task, cluster)
    scn, task = scenario_and_task(args.task, args.goal)
    config = new_config(args, scn, task)
    cluster = connect_cluster(args.ray_address, config.engine)  # before the run directory is made
    if cluster is not None:
        config = dataclasses.replace(config, cluster="ray")
    run = Run(args.out or Path("runs") / f"{scn.name}-{time.strftime('%Y%m%d-%H%M%S')}")
    run.create(config, scn.source, planning_texts(task))
    with run.lock():
        return _train(args, run, config, scn, task, cluster)


def _train(args: argparse.Namespace, run: Run, config: RunConfig, scn: Scenario, task: PlannedTask,
           cluster: ClusterInfo | None) -> int:
    """Trains ``run`` (its repeats one after another) on one rollout, on ``cluster`` if given."""
    print(describe(scn, task))
    print(f"objectives (larger is better): {', '.join(config.objective_names)}")
    print(f"budget {config.budget} evaluations, batches of {config.batch_size}, {config.n_init} random warm-up, "
          f"{config.worlds} worlds, {config.episode_seconds:g} s episodes, seed {config.seed}"
          + (f"; robust protocol: {config.training_rows} evaluations (the most promising sets rolled out again in "
             f"fresh worlds), then a race of the front in {race_episodes(config.budget, config.worlds)} episodes"
             if config.protocol == "robust" else "; the paper's protocol")
          + (f", {config.repeats} repeats" if config.repeats > 1 else "")
          + AFTER_WARM_UP.get(config.optimizer, ""))
    print(describe_prior(config.prior) + (" (the run's own)" if args.resume is not None and config.prior else ""))
    print(f"run directory: {run.path}", flush=True)
    why = config.engine_reason or "the run's own"  # resolved with the configuration; a resumed run's is its own
    print(f"engine: {config.engine} ({why})", flush=True)
    if cluster is not None:
        print(cli_args.describe_cluster(cluster), flush=True)
    cli.interrupt.set_message(f"interrupted: every finished batch is in {run.path}; continue with "
                              f"python -m mjxskill.train {args.task} --resume {run.path}")
    runs = run.sub_runs(config) if config.repeats > 1 else [run]
    sub, sub_config = run, config
    # A Ctrl-C while it is built: nothing is trained yet, and mjxskill.cli.run says where the run is
    rollout = build_rollout(scn, task, config.engine, worlds=config.worlds, episode_seconds=config.episode_seconds,
                            workers=args.workers, cluster=cluster)
    started = time.monotonic()
    try:
        for sub in runs:
            with sub.lock() if sub is not run else contextlib.nullcontext():
                sub_config = sub.config()
                label = f"seed {sub_config.seed}: " if config.repeats > 1 else ""
                evaluate = rollout_evaluator(rollout, sub_config.batch_size, sub_config.seed)
                ev = train(sub, sub_config, evaluate, progress=Progress(sub_config.training_rows, args.quiet, label))
                report.write_run_figures(sub, sub_config, ev)
                print(report.summary(sub, sub_config, ev), flush=True)
                if sub_config.protocol == "robust":  # the pick: the front raced in fresh worlds
                    front, settings = sub.front(sub_config), racing.run_race_settings(sub_config, scn)
                    raced = racing.race(sub.path, front, rollout, settings, sub_config.batch_size)
                    print(racing.describe(raced, front, sub_config, settings), flush=True)
    except KeyboardInterrupt:  # figures of what is done; the CSV already holds every finished batch
        return cli.interrupt.stopped("mjxskill.train", lambda: report.write_run_figures(sub, sub_config, sub.evaluations(sub_config)))
    finally:
        rollout.close()  # the native engine's worker processes; nothing on MJX
    if config.repeats > 1:
        print(report.write_repeats(run, config, runs), flush=True)
    print(f"done in {time.monotonic() - started:.0f} s; results in {run.path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)
