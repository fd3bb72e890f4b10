"""``python -m mjxskill.evaluate RUN_DIR``: the learned Pareto solutions against baselines.

    python -m mjxskill.evaluate runs/push-0
    python -m mjxskill.evaluate runs/push-0 --per-config 10 --random 10

What it runs and writes: ``mjxskill.training.evaluation``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Sequence

from mjxskill import cli
from mjxskill.cli import args as cli_args
from mjxskill.engines import CHOICES, build_rollout, resolve_engine
from mjxskill.errors import CommandError
from mjxskill.training.settings import BY_NAME


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.evaluate", description="Success rates of the Pareto solutions against baselines, per start configuration.")
    parser.add_argument("run", type=Path, help="run directory written by mjxskill.train")
    parser.add_argument("--per-config", type=cli_args.positive_int, default=5, help="worlds per start configuration (default 5)")
    parser.add_argument("--random", type=cli_args.int_at_least(0), default=10, help="random parameter sets (default 10)")
    parser.add_argument("--seed", type=cli_args.seed_type(), default=0, help="seed of the worlds and the random sets")
    parser.add_argument("--batch-size", type=cli_args.positive_int, help="candidates per compiled call (default: the run's batch size)")
    parser.add_argument("--episode-seconds", type=cli_args.setting_type(BY_NAME["episode_seconds"]),
                        help="episode length in s (default: the run's)")
    parser.add_argument("--engine", choices=CHOICES, help="physics engine (default: the run's; the other one checks "
                        "how a solution transfers between engines)")
    return parser


def _main(args: argparse.Namespace) -> int:
    from mjxskill.training.evaluation import build_candidates, evaluate_candidates, plot_boxes, table, write_csv
    from mjxskill.training.run_dir import Run
    from mjxskill.training.run_task import load_run_task

    run = Run(args.run)
    config = run.config()
    if config.repeats > 1:
        raise CommandError(f"{run.path} holds {config.repeats} repeated runs; evaluate one of them, e.g. {run.sub_runs(config)[0].path}")
    front = run.front(config)  # an empty front is refused as select refuses it
    scn, task = load_run_task(run, config)
    candidates = build_candidates(task, front.params, args.random, args.seed)
    n_cfg = len(scn.robot.start_configs) + len(scn.robot.eval_configs)
    print(f"evaluating {len(candidates.names)} parameter sets x {n_cfg} start configurations x {args.per_config} worlds "
          f"({len(scn.robot.start_configs)} known, {len(scn.robot.eval_configs)} unseen)", flush=True)

    engine, why = resolve_engine(args.engine) if args.engine else (config.engine, "the run's")
    print(f"engine: {engine} ({why})", flush=True)
    rollout = build_rollout(scn, task, engine, worlds=1, episode_seconds=args.episode_seconds or config.episode_seconds)
    ev = evaluate_candidates(rollout, candidates, args.per_config, args.seed, args.batch_size or config.batch_size)
    out = run.path / "evaluation"
    out.mkdir(exist_ok=True)
    write_csv(ev, config.parameter_names, out / "evaluation.csv")
    tests = plot_boxes(ev, out / "success.png", f"{config.task}: success rate per start configuration")
    print(table(ev, tests))
    print(f"wrote {out / 'evaluation.csv'} and {out / 'success.png'}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)

