"""``python -m mjxskill.evaluate DIR``: the learned Pareto solutions against baselines.

    python -m mjxskill.evaluate runs/push-0
    python -m mjxskill.evaluate runs/push-0 --per-config 10 --random 10
    python -m mjxskill.evaluate runs/push-x10                 # a repeated run: every seed, then pooled
    python -m mjxskill.evaluate runs/peg-exp                  # an experiment: its protocol, then its report

DIR is a run, a repeated run (``train --repeats``) or an experiment directory
(``mjxskill.runs.layout``); a run or repeated run inside an experiment is evaluated through
the experiment only (its evaluations follow the experiment's protocol). A run's evaluation goes
to ``RUN_DIR/evaluation/`` and is reused when it is current (``mjxskill.evaluation.evaluate_run``). A repeated run evaluates sub-run i in
the worlds of seed ``--seed`` + i and pools them: one picked solution per run against the
baselines (``mjxskill.evaluation.pooled``; each pick validated as an experiment's is, unless
``--validation-per-config 0``, or under the robust protocol its race's winner,
``mjxskill.evaluation.racing``), in ``DIR/evaluation/``. An experiment evaluates every
repetition whose runs are finished with its own protocol (``--validation-per-config`` may change
how its picks are validated), races or validates and confirms its picks, and rewrites its report.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from mjxskill import cli
from mjxskill.cli import args as cli_args
from mjxskill.cli.experiment import change_validation, settle_bound
from mjxskill.engine.build import CHOICES, build_rollout, connect_cluster, resolve_engine
from mjxskill.errors import CommandError
from mjxskill.evaluation.baselines import table
from mjxskill.evaluation.evaluate_run import FOLDER, call_problem, differences_from_earlier, evaluate_run, evaluation_settings
from mjxskill.evaluation.pooled import force_bound, group_means, pick, plot_pooled, pooled_samples, pooled_table, pooled_tests
from mjxskill.evaluation import racing
from mjxskill.evaluation.validation import in_contention, validate, validation_settings
from mjxskill.experiment.directory import Experiment, is_done, repetition_settings, runs_of
from mjxskill.experiment.driver import confirm_timed, evaluate_timed, race_timed, validate_timed
from mjxskill.experiment.picks import repetition_pick
from mjxskill.experiment.report import write_report
from mjxskill.runs.atomic_write import make_folder, refuse_links_out, write_text
from mjxskill.runs.layout import directory_kind, experiment_holding
from mjxskill.runs.run_dir import Run
from mjxskill.runs.run_task import load_run_task
from mjxskill.runs.settings import BY_NAME
from mjxskill.runs.bounds import MAX_PER_CONFIG, MAX_RANDOM_SETS
from mjxskill.scenario.schema import MAX_BATCH

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.native.ray_pool import ClusterInfo
    from mjxskill.engine.protocol import Rollout
    from mjxskill.scenario.schema import Scenario
    from mjxskill.task import PlannedTask


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.evaluate", description="Success rates of the Pareto solutions against baselines, per start configuration.")
    parser.add_argument("run", type=Path, help="run, repeated run or experiment directory")
    parser.add_argument("--per-config", type=cli_args.int_in(1, MAX_PER_CONFIG), help="worlds per start configuration (default 5)")
    parser.add_argument("--random", type=cli_args.int_in(0, MAX_RANDOM_SETS), help="random parameter sets (default 10)")
    parser.add_argument("--seed", type=cli_args.seed_type(), help="seed of the worlds (the evaluation's and a repeated run's "
                        "validation's) and the random sets (default 0; a repeated run's sub-run i: seed + i)")
    parser.add_argument("--batch-size", type=cli_args.int_in(1, MAX_BATCH), help="candidates per compiled call (default: the run's batch size)")
    parser.add_argument("--episode-seconds", type=cli_args.setting_type(BY_NAME["episode_seconds"]),
                        help="episode length in s (default: the run's)")
    cli_args.add_workers_argument(parser)
    cli_args.add_cluster_argument(parser)
    parser.add_argument("--engine", choices=CHOICES, help="physics engine (default: the run's; the other one checks "
                        "how a solution transfers between engines)")
    parser.add_argument("--max-force", type=cli_args.nonnegative_float, metavar="N", help="bound on the commanded force "
                        "of each repeated run's picked solution, N (default: the scenario's pick.max_force)")
    parser.add_argument("--replace", action="store_true", help="replace an earlier evaluation made with other settings "
                        "(without it, evaluate refuses and keeps that one)")
    cli_args.add_validation_arguments(parser, "a repeated run or an experiment, before each run's pick", "default 5; an "
                                              "experiment: its own, which this flag changes (the picks are made again)")
    return parser


def _settings(args, config, seed: int, asked: tuple[str, str] | None) -> dict:
    """The evaluation's settings for a run of ``config`` in the worlds of ``seed``, on the engine
    ``asked`` (``--engine`` resolved: (engine, why)) or the run's."""
    engine = asked[0] if asked else config.engine
    return evaluation_settings(args.per_config or 5, 10 if args.random is None else args.random, seed,
                               args.batch_size or config.batch_size, engine, args.episode_seconds or config.episode_seconds)


def _refuse_large_calls(settings: dict, scn: Scenario) -> None:
    problem = call_problem(settings, scn)
    if problem is not None:
        raise CommandError(problem)


def _rollout(args, scn: Scenario, task: PlannedTask, settings: dict, asked: tuple[str, str] | None,
             cluster: ClusterInfo | None) -> Rollout:
    why = asked[1] if asked else "the run's"
    print(f"engine: {settings['engine']} ({why})", flush=True)
    if cluster is not None:
        print(cli_args.describe_cluster(cluster), flush=True)
    return build_rollout(scn, task, settings["engine"], worlds=1, episode_seconds=settings["episode_seconds"],
                         workers=args.workers, cluster=cluster)


def _say(scn: Scenario, settings: dict, run, config, task: PlannedTask) -> None:
    n = len(run.front(config)) + 1 + settings["random"] + len(task.manual_parameters)
    n_known, n_unseen = len(scn.robot.start_configs), len(scn.robot.eval_configs)
    print(f"{run.path}: evaluating {n} parameter sets x {n_known + n_unseen} start configurations x "
          f"{settings['per_config']} worlds ({n_known} known, {n_unseen} unseen), worlds of seed {settings['seed']}", flush=True)


def _progress(done: int, total: int) -> None:
    print(f"  evaluated {done}/{total} parameter sets", flush=True)


def _main(args: argparse.Namespace) -> int:
    refuse_links_out(args.run)  # before anything in it is read
    asked = resolve_engine(args.engine) if args.engine else None  # (engine, why), once
    kind = directory_kind(args.run)
    if kind == "experiment":
        return _experiment(args, asked)
    exp = experiment_holding(args.run)
    if exp is not None:
        # Its runs' evaluation/ folders are the experiment's, made in its protocol's worlds: an
        # evaluation of the member alone (other seeds, worlds or engine) would replace them.
        raise CommandError(f"{args.run} belongs to the experiment {exp}: evaluate that (python -m mjxskill.evaluate {exp}), "
                           f"whose protocol its runs' evaluations follow; to evaluate them otherwise, copy {args.run} "
                           "out of the experiment first (evaluating it here would replace the evaluations its report is built on)")
    return _runs(args, kind == "repeated", asked)


def _runs(args: argparse.Namespace, repeated: bool, asked: tuple[str, str] | None) -> int:
    run = Run(args.run)
    config = run.config()
    subs = runs_of(run, config)
    for sub in subs:  # every front is there before anything is compiled
        sub.front(sub.config())
    scn, task = load_run_task(run, config)
    bound = force_bound(args.max_force, scn.pick)
    seed = 0 if args.seed is None else args.seed
    for i, sub in enumerate(subs):  # a call the machine cannot hold is refused before anything is written
        _refuse_large_calls(_settings(args, sub.config(), seed + i, asked), scn)
    if not args.replace:
        for i, sub in enumerate(subs):
            _keep_earlier(sub, _settings(args, sub.config(), seed + i, asked))
    settings = _settings(args, config, seed, asked)
    cluster = connect_cluster(args.ray_address, settings["engine"])  # before anything is written
    rollout = _rollout(args, scn, task, settings, asked, cluster)
    results = []
    try:
        for i, sub in enumerate(subs):
            sub_config = sub.config()
            settings = _settings(args, sub_config, seed + i, asked)
            _say(scn, settings, sub, sub_config, task)
            with sub.lock():
                ev, tests, reused = evaluate_run(sub, sub_config, rollout, task, settings, progress=_progress)
            if reused:
                print(f"{sub.path / FOLDER} is current (same settings and front): reused")
            if not repeated:
                print(table(ev, tests))
            print(f"wrote {sub.path / FOLDER}")
            choice = None
            if repeated:
                choice = (_race(sub, sub_config, scn, bound, rollout) if sub_config.protocol == "robust"
                          else _validate(args, sub, sub_config, bound, rollout, settings))
            results.append((sub, sub_config, ev, choice))
    finally:
        rollout.close()
    if repeated:
        print(_pool(run, config, results, bound))
    return 0


FLAGS = {"per_config": "--per-config", "random": "--random", "seed": "--seed", "engine": "--engine",
         "episode_seconds": "--episode-seconds"}


def _keep_earlier(run, settings: dict) -> None:
    """Refuses an evaluation that would replace ``run``'s earlier one made with other settings."""
    differences = differences_from_earlier(run, settings)
    if differences:
        earlier = ", ".join(f"{FLAGS[k]} {old}" for k, old, _ in differences)
        asked = ", ".join(f"{FLAGS[k]} {new}" for k, _, new in differences)
        raise CommandError(f"{run.path / FOLDER} holds an evaluation made with {earlier}; this one ({asked}) would replace "
                           "it, so it is kept: evaluate with --replace to replace it, or evaluate a copy of the run")


def _validate(args, sub, config, bound, rollout: Rollout, settings: dict):
    """The validation of one sub-run's pick within ``bound`` ((N or None, source): ``force_bound``)
    (``mjxskill.evaluation.validation``; None: asked for none)."""
    per = 5 if args.validation_per_config is None else args.validation_per_config
    if not per:
        return None
    k = args.validation_candidates or 3
    front = sub.front(config)
    with sub.lock():
        validation, reused = validate(sub, front, in_contention(front, bound[0], k), rollout,
                                      validation_settings(per, k, settings["seed"], settings["engine"],
                                                          settings["episode_seconds"]))
    print(f"{sub.path}: the pick's {len(validation.rows)} best candidates in {validation.worlds} validation worlds"
          + (" (current: reused)" if reused else ""), flush=True)
    return validation


def _race(sub, config, scn: Scenario, bound, rollout: Rollout):
    """The race of one robust sub-run's front for its pick within ``bound`` ((N or None, source))
    (``mjxskill.evaluation.racing``; finished rounds reused)."""
    settings = dict(racing.run_race_settings(config, scn), max_force=None if bound[0] is None else float(bound[0]))
    front = sub.front(config)
    with sub.lock():
        raced = racing.race(sub.path, front, rollout, settings, config.batch_size)
    print(f"{sub.path}: {racing.describe(raced, front, config, settings)}", flush=True)
    return raced


def _pool(run, config, results, bound) -> str:
    """Picks within ``bound`` ((N or None, source)), pooled groups and tests of a repeated run into
    ``DIR/evaluation/``; a robust sub-run's pick is its race's winner."""
    picks = [pick(sub.front(c), ev, bound[0], source=bound[1], race=choice) if isinstance(choice, racing.Race)
             else pick(sub.front(c), ev, bound[0], choice, bound[1]) for sub, c, ev, choice in results]
    validations = [None if isinstance(v, racing.Race) else v for *_, v in results]
    results = [(sub, c, ev) for sub, c, ev, _ in results]
    samples = pooled_samples([ev for _, _, ev in results], picks)
    tests = pooled_tests(samples)
    out = make_folder(run.path, run.path / FOLDER)  # never through a link below the run
    plot_pooled(samples, out / "success.png", f"{config.task}: success rate per start configuration, {len(results)} runs",
                root=run.path)
    doc = {"runs": [str(sub.path) for sub, _, _ in results],
           "picked": [{"seed": c.seed, "pareto_row": p.row, "bound_N": p.bound, "bound_source": p.source,
                       "validation_success": None if v is None or p.row is None else v.success_of(p.row),
                       "validation_worlds": None if v is None else v.worlds}
                      for (_, c, _), p, v in zip(results, picks, validations)],
           "groups": group_means(samples), "samples": {g: {"known": len(v[0]), "unseen": len(v[1])} for g, v in samples.items()},
           "mann_whitney": tests}
    write_text(out / "pooled.json", json.dumps(doc, indent=1) + "\n", root=run.path)
    lines = [f"seed {c.seed}: picked Pareto row {p.row}" for (_, c, _), p in zip(results, picks)]
    lines.append("bound on the commanded force: " + ("none" if bound[0] is None else f"{bound[0]:g} N") + f", {bound[1]}")
    return "\n".join([*lines, "", pooled_table(samples, tests), f"wrote {out / 'success.png'} and {out / 'pooled.json'}"])


def _experiment(args: argparse.Namespace, asked: tuple[str, str] | None) -> int:
    exp = Experiment(args.run)
    config, protocol = exp.config(), exp.protocol()
    exp.state()  # the wall times the report shows: a damaged file is said before anything is written
    given = {"--per-config": (args.per_config, protocol.per_config), "--random": (args.random, protocol.random_sets),
             "--max-force": (args.max_force, protocol.max_force), "--episode-seconds": (args.episode_seconds, config.episode_seconds),
             "--engine": (asked and asked[0], config.engine)}
    conflicts = [f"{flag} {value} (the experiment has {own})" for flag, (value, own) in given.items()
                 if value is not None and value != own]
    if args.seed is not None:
        conflicts.append(f"--seed {args.seed} (each repetition is evaluated in the worlds of its own seed)")
    if args.replace:
        conflicts.append("--replace (an experiment keeps the evaluations of its protocol)")
    if conflicts:
        raise CommandError(f"{exp.path} is evaluated with its own protocol; drop {', '.join(conflicts)}")
    cluster = connect_cluster(args.ray_address, config.engine)  # before anything is written
    scn, task = load_run_task(exp.optimizer, config)
    ready = [(config.seed + i, opt) for i, (opt, rnd) in enumerate(exp.runs(config))
             if is_done(opt, opt.config()) and is_done(rnd, rnd.config())]
    if not ready:
        raise CommandError(f"{exp.path} has no finished repetition yet; continue it with python -m mjxskill.experiment "
                           f"{config.task} --resume {exp.path}")
    for seed, _ in ready:  # a call the machine cannot hold is refused before anything is written
        settings = repetition_settings(config, protocol, seed)
        _refuse_large_calls({**settings, "batch_size": args.batch_size or settings["batch_size"]}, scn)
    with exp.lock():
        protocol = change_validation(args, exp, protocol)
        protocol = settle_bound(exp, scn)
        if cluster is not None:
            print(cli_args.describe_cluster(cluster), flush=True)
        rollout = build_rollout(scn, task, config.engine, worlds=1, episode_seconds=config.episode_seconds,
                                workers=args.workers, cluster=cluster)
        try:
            for seed, opt in ready:
                settings = repetition_settings(config, protocol, seed)
                if args.batch_size:
                    settings["batch_size"] = args.batch_size
                _say(scn, settings, opt, opt.config(), task)
                ran = evaluate_timed(exp, opt, rollout, task, settings, progress=_progress)
                print(f"wrote {opt.path / 'evaluation'}" if ran else f"{opt.path / 'evaluation'} is current: reused")
                if config.protocol == "robust":
                    raced = race_timed(exp, opt, rollout, config, protocol, seed)
                    print(f"raced the front of seed {seed} for its pick" if raced else
                          f"the race of seed {seed} is finished: reused")
                else:
                    validated = validate_timed(exp, opt, rollout, config, protocol, seed)
                    if validated is not None:
                        print(f"validated the pick's candidates of seed {seed}" if validated else
                              f"the validation of seed {seed} is current: reused")
                confirmed = confirm_timed(exp, opt, rollout, task, config, protocol, seed,
                                          repetition_pick(exp, seed - config.seed))
                if confirmed is not None:
                    print(f"confirmed the pick of seed {seed}" if confirmed else
                          f"the confirmation of seed {seed} is current: reused")
        finally:
            rollout.close()
        print(write_report(exp))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)
