"""``python -m mjxskill.experiment TASK``: the paper's experiment, repeated and reported.

    python -m mjxskill.experiment push                        # the scenario's repetitions, the paper's settings
    python -m mjxskill.experiment peg --repeats 3 --budget 200 --per-config 5 --out runs/peg-exp
    python -m mjxskill.experiment peg --resume runs/peg-exp    # continue a killed experiment

R repetitions of the optimizer (seeds seed..seed+R-1) and R of uniform random search with the
same settings; per repetition the paper's evaluation; ``report.md``, ``report.json`` and the
figures in the experiment directory, rewritten after each repetition. The flags are train's
(``--repeats`` defaults to the scenario's ``repetitions``) plus the evaluation's. What it runs:
``mjxskill.experiment``; the directory: ``mjxskill.runs.layout``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from mjxskill import cli
from mjxskill.cli import args as cli_args
from mjxskill.cli.progress import Progress
from mjxskill.cli.run_settings import (accept_scenario, add_accept_scenario_change, add_setting_arguments, new_config,
                                        resumed_config)
from mjxskill.engine.build import build_rollout, connect_cluster
from mjxskill.errors import CommandError
from mjxskill.experiment.directory import Experiment, Protocol, random_search_config
from mjxskill.experiment.driver import pending_repetitions, run_experiment, share_cluster
from mjxskill.experiment.report import write_report
from mjxskill.evaluation.pooled import GIVEN, force_bound
from mjxskill.runs.atomic_write import refuse_links_out
from mjxskill.runs.run_task import load_run_task, scenario_and_task, scenario_difference
from mjxskill.runs.bounds import MAX_PER_CONFIG, MAX_RANDOM_SETS
from mjxskill.task import describe, planning_texts

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.native.ray_pool import ClusterInfo
    from mjxskill.scenario.schema import Scenario
    from mjxskill.task import PlannedTask

# The evaluation's flags: name -> (default, what the protocol field is called)
EVALUATION_DEFAULTS: dict[str, Any] = {"per_config": 5, "random": 10, "max_force": None}  # max_force None: the scenario's
CONFIRM_DEFAULT = 20  # worlds per start configuration of the pick's confirmation (standard error under a point)
VALIDATION = ("validation_per_config", "validation_candidates")  # the pick's validation: may change on resume


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mjxskill.experiment",
        description="Repeat training (optimizer and random search), evaluate every repetition against the baselines "
                    "and report side by side with the paper.")
    cli_args.add_task_argument(parser)
    add_setting_arguments(parser, skip=("optimizer",), defaults={"repeats": "the scenario's repetitions"})  # it runs both
    cli_args.add_workers_argument(parser)
    cli_args.add_cluster_argument(parser)
    # train's --optimizer, refused by name (argparse would otherwise read it as --optimizer-option)
    parser.add_argument("--optimizer", type=_runs_both, help=argparse.SUPPRESS)
    parser.add_argument("--per-config", type=cli_args.int_in(1, MAX_PER_CONFIG), help="evaluation worlds per start configuration (default 5)")
    parser.add_argument("--random", type=cli_args.int_in(0, MAX_RANDOM_SETS), help="random parameter sets per evaluation (default 10)")
    parser.add_argument("--max-force", type=cli_args.nonnegative_float, metavar="N",
                        help="bound on the picked solution's commanded force, N (default: the scenario's pick.max_force)")
    cli_args.add_validation_arguments(parser, "before each pick of the paper's protocol (the robust protocol races its "
                                              "front instead)", "default 5; on --resume the experiment's own, which "
                                              "this flag changes: the picks are made again, nothing is retrained")
    parser.add_argument("--confirm-per-config", type=cli_args.int_in(0, MAX_PER_CONFIG), metavar="N",
                        help=f"after each pick, the pick and the operators' sets are rolled out in N fresh worlds from "
                             f"every known and unseen start configuration (default {CONFIRM_DEFAULT}; 0: none)")
    parser.add_argument("--out", type=Path, help="experiment directory (default runs/<task>-experiment-<timestamp>)")
    parser.add_argument("--resume", type=Path, metavar="EXP_DIR", help="continue the experiment in EXP_DIR")
    add_accept_scenario_change(parser)
    return parser


def _said(difference) -> str | None:
    return None if difference is None else difference.text()


def _runs_both(text: str) -> str:
    raise argparse.ArgumentTypeError(f"the experiment runs both the optimizer and random search; drop --optimizer {text}")


def _protocol_conflicts(args: argparse.Namespace, protocol) -> list[str]:
    stored = {"per_config": protocol.per_config, "random": protocol.random_sets, "max_force": protocol.max_force,
              "confirm_per_config": protocol.confirm_per_config}
    flags = {"per_config": "--per-config", "random": "--random", "max_force": "--max-force",
             "confirm_per_config": "--confirm-per-config"}
    return [f"{flags[k]} {getattr(args, k)} (the experiment has {stored[k]})" for k in stored
            if getattr(args, k) is not None and getattr(args, k) != stored[k]]


def change_validation(args: argparse.Namespace, exp, protocol):
    """An existing experiment may validate its picks otherwise (``--validation-per-config`` /
    ``--validation-candidates`` of experiment --resume and evaluate: experiment.yaml rewritten,
    nothing retrained or evaluated again). Returns the protocol in force."""
    wanted = {field: getattr(protocol, field) if getattr(args, field) is None else getattr(args, field)
              for field in VALIDATION}
    if all(wanted[field] == getattr(protocol, field) for field in VALIDATION):
        return protocol
    if not wanted["validation_per_config"] and args.validation_candidates is not None:
        raise CommandError(f"--validation-candidates {args.validation_candidates}: {exp.path} picks without validation; "
                           "give --validation-per-config N as well")
    new = exp.set_validation(wanted["validation_per_config"], wanted["validation_candidates"])
    print(f"{exp.path}: the picks are now made {_validation_words(new)} (were {_validation_words(protocol)}); the runs "
          "and evaluations are kept", flush=True)
    return new


def settle_bound(exp, scn: Scenario):
    """The scenario's bound for an experiment made before bounds were stated
    (``Experiment.settle_bound``), said when it changes; returns the protocol in force."""
    protocol, said = exp.settle_bound(scn.pick)
    if said is not None:
        print(said, flush=True)
    return protocol


def bound_words(protocol) -> str:
    """The pick's bound and where it comes from, for a line (the reason is the report's)."""
    if protocol.max_force is None:
        return "none"
    source = protocol.max_force_source or GIVEN
    return f"{protocol.max_force:g} N ({source.split(':')[0]})"


def _validation_words(protocol, config=None) -> str:
    if config is not None and config.protocol == "robust":
        return "by racing the front in fresh worlds (the robust protocol)"
    if not protocol.validation_per_config:
        return "by training success alone (no validation)"
    return (f"after validating the {protocol.validation_candidates} best candidates in {protocol.validation_per_config} "
            "worlds per known start configuration")


def _main(args: argparse.Namespace) -> int:
    started = time.monotonic()
    if args.resume is not None:
        refuse_links_out(args.resume)  # before anything in it is read
        exp = Experiment(args.resume)
        protocol = exp.protocol()
        config = resumed_config(args, exp.optimizer.path)
        cluster = connect_cluster(args.ray_address, config.engine)
        conflicts = _protocol_conflicts(args, protocol)
        if conflicts:
            raise CommandError(f"--resume continues {args.resume} with its own protocol; drop {', '.join(conflicts)}")
        with exp.lock():
            exp.config()  # both runs' configurations agree
            exp.state()  # the wall times the report shows: a damaged file is said before anything is written
            exp.optimizer.check(config)
            exp.random_search.check(random_search_config(config))
            scn, task = load_run_task(exp.optimizer, config, scenario=args.task)
            if _said(scenario_difference(exp.random_search, scn)) != _said(scenario_difference(exp.optimizer, scn)):
                raise CommandError(f"{exp.random_search.path} and {exp.optimizer.path} hold different copies of the "
                                   "scenario; the two would not be comparable")
            if accept_scenario(args, exp.optimizer, scn):
                config = exp.config()
            if config.protocol == "robust" and any(getattr(args, field) is not None for field in VALIDATION):
                raise CommandError(f"{exp.path} picks by racing its front (the robust protocol), not by validation; "
                                   "drop --validation-per-config and --validation-candidates")
            change_validation(args, exp, protocol)  # after every check: a refused resume changes nothing
            settle_bound(exp, scn)
            return _run(args, exp, config, scn, task, started, cluster)
    scn, task = scenario_and_task(args.task, args.goal)
    config = new_config(args, scn, task, defaults={"repeats": scn.optimizer.repetitions})
    cluster = connect_cluster(args.ray_address, config.engine)  # before the experiment directory is made
    if cluster is not None:
        config = dataclasses.replace(config, cluster="ray")
    bound, source = force_bound(args.max_force, scn.pick)
    validation = {field: getattr(args, field) for field in VALIDATION if getattr(args, field) is not None}
    if config.protocol == "robust":
        if validation:
            raise CommandError(f"--{next(iter(validation)).replace('_', '-')}: the robust protocol picks by racing its "
                               "front, not by validation; drop it, or give --protocol paper")
        validation = {"validation_per_config": 0}
    protocol = Protocol(per_config=args.per_config or EVALUATION_DEFAULTS["per_config"],
                        random_sets=EVALUATION_DEFAULTS["random"] if args.random is None else args.random,
                        max_force=bound, max_force_source=source,
                        confirm_per_config=CONFIRM_DEFAULT if args.confirm_per_config is None else args.confirm_per_config,
                        **validation)
    exp = Experiment(args.out or Path("runs") / f"{scn.name}-experiment-{time.strftime('%Y%m%d-%H%M%S')}")
    exp.create(config, protocol, scn.source, planning_texts(task))
    with exp.lock():
        return _run(args, exp, config, scn, task, started, cluster)


def _run(args: argparse.Namespace, exp, config, scn: Scenario, task: PlannedTask, started: float,
         cluster: ClusterInfo | None) -> int:
    """Runs the experiment's repetitions left, on ``cluster`` if given (several at a time there)."""
    protocol = exp.protocol()
    print(describe(scn, task))
    print(f"experiment: {config.repeats} repetitions (seeds {config.seed}..{config.seed + config.repeats - 1}) of the "
          f"optimizer and of random search; {config.training_rows} evaluations in batches of {config.batch_size}, "
          f"{config.n_init} random warm-up, {config.worlds} worlds, {config.episode_seconds:g} s episodes")
    print(f"evaluation per repetition: {protocol.per_config} worlds per start configuration, {protocol.random_sets} "
          f"random sets; pick bound " + bound_words(protocol)
          + f"; picks made {_validation_words(protocol, config)}"
          + (f"; the pick and the operators' sets confirmed in {protocol.confirm_per_config} worlds per start "
             "configuration" if protocol.confirm_per_config else ""))
    print(f"experiment directory: {exp.path}", flush=True)
    why = config.engine_reason or "the experiment's own"  # resolved with the configuration; a resumed one's is its own
    print(f"engine: {config.engine} ({why})", flush=True)
    at_a_time, actors = 1, None
    if cluster is not None:  # the repetitions left share the cluster's CPUs (one rollout each)
        at_a_time, actors = share_cluster(cluster.cpus, pending_repetitions(exp))
        print(cli_args.describe_cluster(cluster, at_a_time, actors), flush=True)
    cli.interrupt.set_message(f"interrupted: every finished batch and evaluated chunk is in {exp.path}; continue with "
                              f"python -m mjxskill.experiment {args.task} --resume {exp.path}")
    # A Ctrl-C while it is built: nothing new is trained yet, and mjxskill.cli.run says where the experiment is
    rollouts = []  # one per repetition running at the same time
    try:
        for _ in range(at_a_time):
            rollouts.append(build_rollout(scn, task, config.engine, worlds=config.worlds,
                                          episode_seconds=config.episode_seconds, workers=args.workers,
                                          cluster=cluster, actors=actors))
    except BaseException:
        for rollout in rollouts:
            rollout.close()
        raise
    try:
        exp.add_session(time.monotonic() - started, config.engine, cluster, at_a_time)

        def progress_for(run_config):
            kind = "random search" if run_config.optimizer == "random" else "optimizer"
            return Progress(run_config.training_rows, args.quiet, f"{kind} seed {run_config.seed}: ")

        def evaluation_progress(done: int, total: int) -> None:
            print(f"  evaluated {done}/{total} parameter sets ({time.monotonic() - started:.0f} s)", flush=True)

        run_experiment(exp, rollouts if at_a_time > 1 else rollouts[0], task, progress_for=progress_for,
                       log=lambda text: print(text, flush=True), evaluation_progress=evaluation_progress)
    except KeyboardInterrupt:  # the report of what is finished; every batch and chunk is on disk already
        return cli.interrupt.stopped("mjxskill.experiment", lambda: write_report(exp))
    finally:
        for rollout in rollouts:
            rollout.close()  # the native engine's worker processes or Ray actors; nothing on MJX
    print(f"done in {time.monotonic() - started:.0f} s; report in {exp.path / 'report.md'}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)
