"""``python -m mjxskill.train TASK``: learn the free parameters of a planned task.

    python -m mjxskill.train push            # the paper's settings: 400 evaluations, 7 worlds
    python -m mjxskill.train peg --budget 200 --batch-size 8 --init 40 --worlds 7 --seed 3 --out runs/peg-3
    python -m mjxskill.train push --resume runs/push-0
    python -m mjxskill.train push --repeats 10 --out runs/push-x10

Scenario -> plan -> eBT -> compiled rollout -> optimizer loop. Every batch is appended to
``evaluations.csv`` and flushed before the next proposal; the optimizer state is replayed from
that file on ``--resume`` (see ``mjxskill.run_dir``), so an interrupted run continues to the
same budget and ends with the results of an uninterrupted one.

Hypervolume (progress bar, ``hypervolume.png``): computed in the optimizer's space, the
negated objectives (minimized), with a reference point fixed once the warm-up is complete:
per objective, the worst warm-up value plus 10 % of the warm-up range (1e-9 if the range is
0). It is stored in ``run_state.json`` and is a pure function of the warm-up rows, so a resumed
run reports the same numbers.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Callable, NamedTuple, Sequence

import numpy as np

from mjxskill import cli
from mjxskill.run_dir import OPTIMIZER_STATE, Evaluations, Run, RunConfig, batch_sizes

HV_MARGIN = 0.1  # reference point = worst warm-up value + this fraction of the warm-up range


class BatchResult(NamedTuple):
    """What one evaluated batch of B parameter sets gives: objectives (B, O), larger is better;
    success_rate (B,) in [0, 1]; max_force (B,) N."""

    objectives: np.ndarray
    success_rate: np.ndarray
    max_force: np.ndarray


# (params (B, P) float64, batch index) -> BatchResult. Must be a pure function of its inputs:
# resuming relies on a re-run batch giving the same numbers.
BatchEvaluator = Callable[[np.ndarray, int], BatchResult]


def rollout_key(seed: int, iteration: int):
    """PRNG key of batch ``iteration``'s worlds: depends only on (seed, batch index), so a
    resumed run draws the same worlds. A stream separate from the optimizer's keys."""
    import jax

    return jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(seed), 0x0ED0), iteration)


def rollout_evaluator(rollout, batch_size: int, seed: int) -> BatchEvaluator:
    """Evaluates batches with a compiled rollout, always at ``batch_size`` parameter sets (short
    batches are padded with copies of their first row) so that a run compiles once."""

    def evaluate(params: np.ndarray, iteration: int) -> BatchResult:
        n = len(params)
        padded = np.concatenate([params, np.repeat(params[:1], batch_size - n, axis=0)])
        out = rollout(padded, rollout_key(seed, iteration))
        success = np.asarray(out.success, np.float64)[:n]
        return BatchResult(
            objectives=np.asarray(out.objectives, np.float64)[:n],
            success_rate=success.mean(axis=1),
            max_force=np.asarray(out.metrics["max_force"], np.float64)[:n].mean(axis=1),
        )

    return evaluate


# -- hypervolume ----------------------------------------------------------------------------------
def hypervolume_reference(warmup_objectives: np.ndarray) -> np.ndarray:
    """(O,) reference point in the minimized space (-objectives) from the (n_init, O) warm-up."""
    z = -np.asarray(warmup_objectives, np.float64)
    z = np.where(np.isfinite(z), z, np.nan)
    worst, best = np.nanmax(z, axis=0), np.nanmin(z, axis=0)
    span = np.where(worst > best, worst - best, 1e-9)
    return worst + HV_MARGIN * span


def hypervolume_history(ev: Evaluations, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hypervolume after each batch: (evaluations done (k,), hypervolume (k,))."""
    from mjxskill.gp import hypervolume

    ends = np.flatnonzero(np.diff(np.append(ev.iteration, -1)) != 0) + 1
    return ends, np.array([hypervolume(-ev.objectives[:e], ref) for e in ends])


def reference_from(run: Run, config: RunConfig, ev: Evaluations) -> np.ndarray | None:
    """The stored reference point, or the one the warm-up defines (written once known)."""
    state = run.run_state()
    if "hv_reference" in state:
        return np.asarray(state["hv_reference"], np.float64)
    if len(ev) < min(config.n_init, config.budget):
        return None
    ref = hypervolume_reference(ev.objectives[: config.n_init])
    run.write_run_state({**state, "hv_reference": ref.tolist(), "hv_space": "negated objectives (minimized)"})
    return ref


def pareto_mask_of(ev: Evaluations) -> np.ndarray:
    from mjxskill.gp import pareto_mask

    return pareto_mask(-ev.objectives) if len(ev) else np.zeros(0, bool)


# -- the loop -------------------------------------------------------------------------------------
def optimizer_config(config: RunConfig):
    from mjxskill.gp import MOBOConfig, acquisition_settings

    return MOBOConfig(
        bounds=config.bounds,
        n_objectives=len(config.objective_names),
        batch_size=config.batch_size,
        n_init=config.n_init,
        seed=config.seed,
        acquisition=acquisition_settings(config.optimizer_options),
    )


def train(run: Run, config: RunConfig, evaluate: BatchEvaluator, *, progress: "Progress | None" = None) -> Evaluations:
    """Runs (or continues) the optimizer loop of ``run`` to ``config.budget`` evaluations.

    The optimizer state is replayed from the rows on disk; each batch is appended and flushed
    before the next proposal. Returns all evaluations.
    """
    from mjxskill import gp

    ev = run.repair(config)
    state = gp.init(optimizer_config(config))
    if len(ev):
        state = gp.tell(state, ev.params, -ev.objectives)
    sizes = list(batch_sizes(config.budget, config.batch_size, config.n_init))
    batch = int(np.searchsorted(np.cumsum(sizes), len(ev), side="right"))
    if progress:
        progress.start(ev, reference_from(run, config, ev))
    while len(ev) < config.budget:
        x = gp.ask(state, num=sizes[batch])
        result = evaluate(x, batch)
        new = Evaluations(np.full(len(x), batch), x, *(np.asarray(a, np.float64) for a in result))
        run.append(new)  # on disk before anything else happens
        ev = ev.concat(new)
        state = gp.tell(state, x, -new.objectives)
        gp.save_state(state, run.path / OPTIMIZER_STATE)
        run.write_pareto(config, ev, pareto_mask_of(ev))
        if progress:
            progress.update(new, ev, reference_from(run, config, ev))
        batch += 1
    run.write_pareto(config, ev, pareto_mask_of(ev))
    if progress:
        progress.close()
    return ev


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
    cli.add_task_argument(parser)
    parser.add_argument("--budget", type=cli.positive_int, help="evaluations (parameter sets) per run (default: the scenario's)")
    parser.add_argument("--batch-size", type=cli.positive_int, help="parameter sets per batch (default: the scenario's)")
    parser.add_argument("--init", type=cli.int_at_least(2), help="random warm-up evaluations (default: the scenario's)")
    parser.add_argument("--worlds", type=cli.positive_int, help="randomized worlds per parameter set (default: the scenario's)")
    parser.add_argument("--seed", type=cli.int_at_least(0), help="seed of the optimizer and the worlds (default: the scenario's)")
    parser.add_argument("--episode-seconds", type=cli.positive_float, help="episode length in s (default: the scenario's)")
    parser.add_argument("--goal", help="PDDL goal to plan instead of the scenario's")
    parser.add_argument("--repeats", type=cli.positive_int, help="independent runs with seeds seed..seed+N-1 (default 1)")
    parser.add_argument("--out", type=Path, help="run directory (default runs/<task>-<timestamp>)")
    parser.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue the run in RUN_DIR to its budget")
    parser.add_argument("--quiet", action="store_true", help="no progress bar: one log line per batch")
    parser.add_argument("--optimizer-option", action="append", type=optimizer_option, metavar="KEY=VALUE", default=None,
                        help="an acquisition setting of mjxskill.gp (AcquisitionSettings), e.g. n_raw=256 or "
                             "model=scalarized (repeatable; stored with the run)")
    return parser


def optimizer_option(text: str) -> tuple[str, int | float | str]:
    """``KEY=VALUE`` for an acquisition setting of mjxskill.gp (argparse type): the value as a
    number when it reads as one, else the string. Keys and values are checked together by
    ``gp.acquisition_settings`` in ``resolve_config`` (one setting can bound another)."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    for kind in (int, float):
        try:
            return key, kind(value)
        except ValueError:
            pass
    return key, value


SETTING_FLAGS = {"budget": "budget", "batch_size": "batch_size", "init": "n_init", "worlds": "worlds",
                 "seed": "seed", "episode_seconds": "episode_seconds", "goal": "goal", "repeats": "repeats"}


def resolve_config(args: argparse.Namespace, scn) -> RunConfig:
    """The run configuration of a new run: flags over the scenario's defaults."""
    opt = scn.optimizer
    config = RunConfig(
        task=scn.name,
        # a scenario name stays a name; a YAML path is made absolute for evaluate/select
        scenario=args.task if Path(args.task).name == args.task and not args.task.endswith((".yaml", ".yml")) else str(Path(args.task).resolve()),
        goal=scn.task.goal,
        parameter_names=tuple(scn.parameter_names),
        parameter_units=tuple(scn.parameter_units),
        bounds=(tuple(map(float, scn.bounds[0])), tuple(map(float, scn.bounds[1]))),
        objective_names=tuple(scn.objective_names),
        budget=args.budget if args.budget is not None else opt.budget,
        batch_size=args.batch_size if args.batch_size is not None else opt.batch_size,
        n_init=args.init if args.init is not None else opt.n_init,
        worlds=args.worlds if args.worlds is not None else scn.randomization.n_worlds,
        seed=args.seed if args.seed is not None else opt.seed,
        episode_seconds=float(args.episode_seconds if args.episode_seconds is not None else scn.episode_seconds),
        repeats=args.repeats or 1,
        optimizer_options=dict(args.optimizer_option or []),
    )
    try:
        optimizer_config(config)
    except ValueError as err:  # gp names the bad setting
        raise cli.CommandError(f"--optimizer-option: {err}") from None
    if config.n_init > config.budget:
        raise cli.CommandError(f"--init {config.n_init} exceeds the budget of {config.budget} evaluations")
    if not config.parameter_names:
        raise cli.CommandError(f"the plan for {config.goal!r} leaves no parameter to learn")
    return config


def scenario_for(task: str, goal: str | None, expect_task: str | None = None, where: Path | None = None):
    """Loads the scenario and, for a user goal, plans it (the rollout runs ``scn.task``).
    expect_task: the task name a run directory ``where`` was trained on (checked first)."""
    import dataclasses

    from mjxskill.plan import plan_task
    from mjxskill.scenario import load_scenario

    scn = load_scenario(task)
    if expect_task is not None and scn.name != expect_task:
        raise cli.CommandError(f"{where} is a run of task {expect_task!r}, not {scn.name!r}")
    if goal is not None and goal != scn.task.goal:
        scn = dataclasses.replace(scn, task=plan_task(scn, goal))
    return scn


def _resumed_config(args: argparse.Namespace) -> RunConfig:
    run = Run(args.resume)
    config = run.config()
    if args.optimizer_option and dict(args.optimizer_option) != config.optimizer_options:
        raise cli.CommandError(f"--resume continues {args.resume} with its own optimizer options {config.optimizer_options}; drop --optimizer-option")
    given = {flag: getattr(args, flag) for flag in SETTING_FLAGS if getattr(args, flag) is not None}
    conflicts = [f"--{flag.replace('_', '-')} {value} (the run has {getattr(config, SETTING_FLAGS[flag])})"
                 for flag, value in given.items() if value != getattr(config, SETTING_FLAGS[flag])]
    if conflicts:
        raise cli.CommandError(f"--resume continues {args.resume} with its own settings; drop {', '.join(conflicts)}")
    if args.out is not None and Path(args.out).resolve() != Path(args.resume).resolve():
        raise cli.CommandError("--out and --resume name different directories; --resume writes into its own")
    return config


def _check_same_task(scn, config: RunConfig, where: Path) -> None:
    mismatch = []
    if scn.name != config.task:
        mismatch.append(f"task {config.task!r}, not {scn.name!r}")
    elif tuple(scn.parameter_names) != config.parameter_names:
        mismatch.append(f"parameters {list(config.parameter_names)}, not {list(scn.parameter_names)}")
    elif tuple(scn.objective_names) != config.objective_names:
        mismatch.append(f"objectives {list(config.objective_names)}, not {list(scn.objective_names)}")
    elif not np.array_equal(np.asarray(scn.bounds, np.float64), np.asarray(config.bounds, np.float64)):
        mismatch.append(f"parameter bounds {[list(b) for b in config.bounds]}, not the scenario's current "
                        f"{np.asarray(scn.bounds).tolist()} (the scenario file changed since)")
    if mismatch:
        raise cli.CommandError(f"{where} is a run of {mismatch[0]}: use it with its own task")


def _main(args: argparse.Namespace) -> int:
    from mjxskill.plan import describe

    if args.resume is not None:
        config = _resumed_config(args)
        scn = scenario_for(args.task, config.goal, expect_task=config.task, where=args.resume)
        _check_same_task(scn, config, args.resume)
        run = Run(args.resume)
    else:
        scn = scenario_for(args.task, args.goal)
        config = resolve_config(args, scn)
        out = args.out or Path("runs") / f"{scn.name}-{time.strftime('%Y%m%d-%H%M%S')}"
        run = Run(out)
        run.create(config, scn.source, planning_texts(scn))
        if config.repeats > 1:
            for sub in run.sub_runs(config):
                sub.create(config.sub_run(int(sub.path.name.split("-")[1])), scn.source, planning_texts(scn))

    print(describe(scn, scn.task))
    print(f"objectives (larger is better): {', '.join(config.objective_names)}")
    print(f"budget {config.budget} evaluations, batches of {config.batch_size}, {config.n_init} random warm-up, "
          f"{config.worlds} worlds, {config.episode_seconds:g} s episodes, seed {config.seed}"
          + (f", {config.repeats} repeats" if config.repeats > 1 else ""))
    print(f"run directory: {run.path}", flush=True)

    from mjxskill.rollout import compile_rollout
    from mjxskill import report

    rollout = compile_rollout(scn, worlds=config.worlds, episode_seconds=config.episode_seconds)
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
    if config.repeats > 1:
        print(report.write_repeats(run, config, runs), flush=True)
    print(f"done in {time.monotonic() - started:.0f} s; results in {run.path}")
    return 0


def planning_texts(scn) -> dict[str, str]:
    from mjxskill.ebt.nodes import render

    task = scn.task
    return {
        "domain.pddl": task.domain_pddl,
        "problem.pddl": task.problem_pddl,
        "plan.txt": f"; goal: {task.goal}\n" + "\n".join(task.plan),
        "bt.txt": render(task.tree),
    }


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
