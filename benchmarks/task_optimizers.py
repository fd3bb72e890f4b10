"""Our optimizer against what a robotics engineer would pick instead, on the robot tasks
themselves (issue 35): push and peg, native engine, full episodes.

    python benchmarks/task_optimizers.py --seeds 5 --budget 200            # push and peg, every method
    python benchmarks/task_optimizers.py --tasks peg --methods mjxskill.gp,optuna-tpe --seeds 10
    python benchmarks/task_optimizers.py --quick --out /tmp/quick          # minutes: the pipeline, not the numbers
    python benchmarks/task_optimizers.py --report benchmarks/results/<date>/task_optimizers.jsonl

Every method is a ``train`` run through the training loop's own functions
(``mjxskill.training.loop.train``) with the same budget, batch size, warm-up, worlds, episode
length and world seeds (the worlds of batch b of seed s are drawn from (s, b) whatever the
method): ``mjxskill.gp`` (``--optimizer mobo``, its defaults), ``optuna-nsga2``,
``optuna-tpe``, ``optuna-gp`` (needs PyTorch; not in the default methods),
``botorch-qlognehvi`` (BoTorch's multi-objective tutorial about the run's reference point,
``mjxskill.training.botorch_search``; needs the ``botorch`` extra, not in the default methods)
and ``random``. Every method of a seed shares its warm-up rows (the Bayesian optimizer's uniform
draws).

Hypervolume: in the minimized space (negated objectives), about one reference point per task,
the worst value of each objective over the union of the warm-ups of every finished run of the
task plus 10 % of that union's range (``mjxskill.training.front.hypervolume_reference``). As
the warm-up is shared by the methods of a seed, no method's proposals move the reference.

Each run is a run directory under ``OUT/runs/<task>/<method>/seed-<s>`` (each batch on disk
before the next; a killed benchmark started again with the same flags resumes the unfinished
runs and skips the finished ones); the planned task's ``domain.pddl``, ``problem.pddl``,
``plan.txt`` and ``bt.txt`` are written once per task, in ``OUT/runs/<task>/``, and the runs
hold no copies of them. After each finished run ``OUT/task_optimizers.jsonl`` is
rewritten whole, one line per finished run: ``task``, ``method``, ``seed``, ``budget``,
``batch_size``, ``n_init``, ``worlds``, ``episode_seconds``, ``optimizer_options`` (ours: the
acquisition settings given by ``--optimizer-option``), ``hypervolume`` (final, about the
task's reference), ``hypervolume_history`` (after each batch), ``reference`` (rewards, larger
is better), ``front`` (the final Pareto rewards), ``ask_seconds`` (the optimizer's own wall
time per batch after the warm-up, the proposal alone), ``run_dir`` and the run's pick: as an
experiment picks (its ``CANDIDATES`` best Pareto solutions within the scenario's force bound
validated in ``PER_CONFIG`` fresh worlds per known start configuration, the most successful
picked, ties by time), ``pick_params``, ``pick_training_success``, ``pick_validation_success``
(the best of the candidates there, so biased upwards) and ``pick_fresh_success`` (the pick again
in ``FRESH_PER_CONFIG`` worlds per known configuration of a stream of their own:
``pick_fresh_worlds``). ``--report`` prints, per task and method, the median and quartiles of
the final hypervolume, a two-sided Mann-Whitney U p of ``mjxskill.gp`` against each other
method, and the median pick's fresh success; then the median hypervolume at 25, 50, 75 and
100 % of the budget and where ours trails.

``--quick``: push and peg, 1 seed, budget 12 in batches of 6 after a 6-point warm-up, 1 world,
0.3 s episodes and a cheap acquisition search for ``mjxskill.gp``: what the test runs.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import mjxskill  # noqa: E402,F401  (XLA flags before any JAX computation)
from mjxskill.cli.run_settings import optimizer_option  # noqa: E402
from mjxskill.engine.build import build_rollout  # noqa: E402
from mjxskill.errors import UserError  # noqa: E402
from mjxskill.evaluation.pooled import validated_best  # noqa: E402
from mjxskill.evaluation.validation import in_contention, validate, validate_rows, validation_settings  # noqa: E402
from mjxskill.experiment.directory import is_done  # noqa: E402
from mjxskill.gp import hypervolume, pareto_mask  # noqa: E402
from mjxskill.runs.atomic_write import write_json, write_text  # noqa: E402
from mjxskill.runs.run_dir import Run  # noqa: E402
from mjxskill.scenario import load_scenario  # noqa: E402
from mjxskill.task import plan_task, planning_texts  # noqa: E402
from mjxskill.training import loop  # noqa: E402
from mjxskill.training.configure import new_run_config  # noqa: E402
from mjxskill.training.front import hypervolume_reference  # noqa: E402
from mjxskill.training.optimizers import Optimizer, make_optimizer  # noqa: E402

METHODS = {"mjxskill.gp": "mobo", "optuna-nsga2": "optuna-nsga2", "optuna-tpe": "optuna-tpe",
           "optuna-gp": "optuna-gp", "botorch-qlognehvi": "botorch-qlognehvi", "random": "random"}
DEFAULT_METHODS = ("mjxskill.gp", "optuna-nsga2", "optuna-tpe", "random")
OURS = "mjxskill.gp"
JSONL = "task_optimizers.jsonl"
ASK_TIMES = "ask_seconds.csv"  # in each run directory: rows before the batch, seconds of the proposal
# The pick, as an experiment makes it (mjxskill.evaluation.validation): the CANDIDATES Pareto
# solutions within the scenario's force bound with the best training success, rolled out again in
# PER_CONFIG fresh worlds from each known start configuration; the pick is the one an experiment
# takes (mjxskill.evaluation.pooled.validated_best: the most successful, of equal ones the
# fastest). Its success there is the best of CANDIDATES draws, so it is checked once more in
# FRESH_PER_CONFIG worlds per configuration from a stream of their own.
CANDIDATES, PER_CONFIG, FRESH_PER_CONFIG = 3, 5, 10
FRESH_SEED = 1_000_003  # added to the run's seed: the fresh check's worlds, apart from the validation's
PICK = "task_optimizers_pick.json"  # in each run directory: the fresh check, reused when current
QUICK = dict(tasks="push,peg", seeds=1, budget=12, batch=6, init=6, worlds=1, episode_seconds=3.0)
QUICK_GP = dict(n_raw=64, n_restarts=2, n_opt_steps=10, fit_starts=1, fit_steps=10)


def parse(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", default="push,peg", help="comma-separated scenarios (default push,peg)")
    ap.add_argument("--methods", default=",".join(DEFAULT_METHODS), help=f"comma-separated, of {', '.join(METHODS)}")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--budget", type=int, default=200)
    ap.add_argument("--batch", type=int, default=6)
    ap.add_argument("--init", type=int, default=48)
    ap.add_argument("--worlds", type=int, default=7)
    ap.add_argument("--episode-seconds", type=float, default=None, help="default: the scenario's (full episodes)")
    ap.add_argument("--optimizer-option", action="append", type=optimizer_option, metavar="KEY=VALUE", default=None,
                    help="a setting of mjxskill.gp's acquisition for its runs (as train's); repeatable")
    ap.add_argument("--quick", action="store_true", help="tiny runs of every task and method (the test)")
    ap.add_argument("--out", type=Path, default=None,
                    help=f"results folder (default benchmarks/results/<date>/task_optimizers)")
    ap.add_argument("--report", type=Path, nargs="+", metavar="JSONL", help="print the table of these files and stop")
    args = ap.parse_args(argv)
    if args.quick:
        for key, value in QUICK.items():
            setattr(args, key, value)
    args.task_list = [t for t in args.tasks.split(",") if t]
    args.method_list = [m for m in args.methods.split(",") if m]
    unknown = [m for m in args.method_list if m not in METHODS]
    if unknown:
        ap.error(f"--methods: unknown {', '.join(unknown)}; the methods are {', '.join(METHODS)}")
    if args.out is None:
        args.out = ROOT / "benchmarks" / "results" / datetime.date.today().isoformat() / "task_optimizers"
    return args


class TimedOptimizer:
    """The run's optimizer, each proposal after the warm-up timed and appended to the run's
    ASK_TIMES (rows so far, seconds) before its batch is evaluated: the optimizer's own time per ask."""

    def __init__(self, optimizer: Optimizer, run_path: Path, n_init: int):
        self.optimizer, self.run_path, self.n_init = optimizer, run_path, n_init
        self.name = optimizer.name

    def init(self):
        return self.optimizer.init()

    def ask(self, state, size: int) -> np.ndarray:
        started = time.perf_counter()
        x = self.optimizer.ask(state, size)
        seconds = time.perf_counter() - started
        if len(state.x) >= self.n_init:
            with open(self.run_path / ASK_TIMES, "a", newline="") as fh:
                fh.write(f"{len(state.x)},{seconds:.6f}\n")
        return x

    def tell(self, state, x, y, noise=None):
        return self.optimizer.tell(state, x, y, noise)


def ask_seconds(run_path: Path) -> list[float]:
    """Seconds per proposal in batch order; a batch asked again after a kill: its last ask."""
    path = run_path / ASK_TIMES
    if not path.is_file():
        return []
    by_rows = {int(rows): float(s) for rows, s in csv.reader(path.read_text().splitlines())}
    return [by_rows[rows] for rows in sorted(by_rows)]


def write_planning(folder: Path, task) -> None:
    """The planned task's files in ``folder`` (``OUT/runs/<task>``), once for its runs as an
    experiment writes them once for its own: a file there already is kept (that of the first
    runs, which a later invocation adds to)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in planning_texts(task).items():
        if not os.path.lexists(folder / name):
            write_text(folder / name, text if text.endswith("\n") else text + "\n")


def run_one(rollout, scn, task, method: str, seed: int, args, path: Path):
    """The run of ``method`` and ``seed`` in ``path``, created or resumed; its evaluations."""
    # The paper's protocol: the optimizers are compared on the same rows, each set once in its
    # batch's worlds (the robust protocol's replication is the Bayesian optimizer's own).
    settings = dict(budget=args.budget, batch_size=args.batch, n_init=args.init, worlds=args.worlds, seed=seed,
                    episode_seconds=args.episode_seconds or scn.episode_seconds, engine="native",
                    optimizer=METHODS[method], protocol="paper")
    options = {**(QUICK_GP if args.quick else {}), **dict(args.optimizer_option or [])} if method == OURS else {}
    config = new_run_config(scn, task, scn.name, settings, options)
    run = Run(path)
    if not (path / "config.yaml").is_file():
        run.create(config, scn.source, {})  # the task's planning files: once, write_planning
    else:
        run.check(config)
    optimizer = TimedOptimizer(make_optimizer(config.optimizer, config), path, config.n_init)
    with run.lock():
        return loop.train(run, config, loop.rollout_evaluator(rollout, config.batch_size, seed), optimizer=optimizer)


def validated_pick(run: Run, rollout, scn, seed: int, per_config: int, fresh_per_config: int) -> dict:
    """The run's pick as an experiment validates it and its success in fresh worlds (fields of
    a result line; all None when no Pareto solution is within the bound)."""
    config = run.config()
    front = run.front(config)
    bound = scn.pick.max_force if scn.pick is not None else None
    rows = in_contention(front, bound, CANDIDATES)
    if not rows:
        return {"pick_params": None, "pick_validation_success": None, "pick_fresh_success": None}
    settings = validation_settings(per_config, CANDIDATES, seed, "native", config.episode_seconds)
    with run.lock():
        checked, _ = validate(run, front, rows, rollout, settings)
    row = validated_best(front, rows, checked)
    best = rows.index(row)
    params = front.params[row]
    fresh = {"params": params.tolist(), "per_config": fresh_per_config, "seed": seed + FRESH_SEED,
             "episode_seconds": config.episode_seconds}
    stored = run.path / PICK
    try:  # the benchmark's own cache: anything unreadable or of other worlds is made again
        doc = json.loads(stored.read_text()) if stored.is_file() else {}
    except (OSError, ValueError):
        doc = {}
    doc = doc if isinstance(doc, dict) else {}
    if {k: doc.get(k) for k in fresh} != fresh or not isinstance(doc.get("success"), float):
        success, _ = validate_rows(rollout, params[None], fresh_per_config, seed + FRESH_SEED)
        doc = {**fresh, "success": float(success[0])}
        write_json(stored, doc)
    return {"pick_params": params.tolist(), "pick_training_success": float(front.success_rate[row]),
            "pick_validation_success": float(checked.success[best]), "pick_validation_worlds": checked.worlds,
            "pick_fresh_success": doc["success"],
            "pick_fresh_worlds": fresh_per_config * len(scn.robot.start_configs)}


def record(run: Run, task: str, method: str, seed: int, args) -> dict:
    config = run.config()
    ev = run.evaluations(config)
    return {"task": task, "method": method, "seed": seed, "budget": config.budget, "batch_size": config.batch_size,
            "n_init": config.n_init, "worlds": config.worlds, "episode_seconds": config.episode_seconds,
            "optimizer_options": dict(config.optimizer_options),
            "objectives": config.objective_names, "iteration": ev.iteration.tolist(), "y": ev.objectives.tolist(),
            "ask_seconds": ask_seconds(run.path), "run_dir": str(run.path)}


def batch_history(objectives, iteration, reference) -> dict:
    """``hypervolume_history`` (the hypervolume of the rows up to the end of each batch, about
    ``reference``; objectives and reference are rewards, larger is better) and ``evaluations``
    (the rows at each batch's end)."""
    z, it = -np.asarray(objectives, dtype=float), np.asarray(iteration)
    ends = np.flatnonzero(np.diff(np.append(it, -1)) != 0) + 1
    return {"hypervolume_history": [float(hypervolume(z[:e], -np.asarray(reference))) for e in ends],
            "evaluations": ends.tolist()}


def with_hypervolumes(records: list[dict]) -> list[dict]:
    """Each record with the hypervolumes about its task's reference point (the union of the
    task's warm-ups), in the negated (minimized) objectives."""
    out = []
    for task in dict.fromkeys(r["task"] for r in records):
        mine = [r for r in records if r["task"] == task]
        warmups = np.concatenate([np.asarray(r["y"])[: r["n_init"]] for r in mine])
        ref = hypervolume_reference(warmups)
        for r in mine:
            history = batch_history(np.asarray(r["y"]), r["iteration"], -ref)
            front = np.asarray(r["y"])[pareto_mask(-np.asarray(r["y"]))]
            entry = {k: v for k, v in r.items() if k not in ("y", "iteration")}
            out.append({**entry, "hypervolume": history["hypervolume_history"][-1], **history,
                        "reference": (-ref).tolist(), "reference_from": f"warm-ups of {len(mine)} runs of {task}",
                        "front": front.tolist()})
    return out


def finished_runs(out: Path, task: str) -> list[tuple[str, int, Path]]:
    """(method, seed, path) of every run of ``task`` under ``out`` that has spent its budget."""
    found = []
    for method in METHODS:
        for path in sorted((out / "runs" / task / method).glob("seed-*"), key=lambda p: p.name):
            if not path.name[5:].isdigit() or not (path / "config.yaml").is_file():
                continue
            run = Run(path)
            if is_done(run, run.config()):
                found.append((method, int(path.name[5:]), path))
    return found


def benchmark(args) -> list[dict]:
    """Runs (or resumes) every run asked for. The JSONL holds every finished run under
    ``args.out``: those of other invocations too (other methods or seeds of a task: rebuilt
    from their run directories, the reference from all of them; other tasks: their lines
    kept as written)."""
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / JSONL
    earlier = read_rows([path], "the results of an earlier run,") if path.is_file() else []
    kept = [r for r in earlier if r["task"] not in args.task_list]
    records = []

    def write():
        write_text(path, "".join(json.dumps(r) + "\n" for r in kept + with_hypervolumes(records)))

    for task_name in args.task_list:
        scn = load_scenario(task_name)
        task = plan_task(scn)
        write_planning(args.out / "runs" / task_name, task)
        seconds = args.episode_seconds or scn.episode_seconds
        print(f"{task_name}: native engine, {args.worlds} worlds, {seconds:g} s episodes, budget {args.budget} = "
              f"{args.init} warm-up + batches of {args.batch}, seeds {args.first_seed}..{args.first_seed + args.seeds - 1}",
              flush=True)
        with build_rollout(scn, task, "native", worlds=args.worlds, episode_seconds=seconds) as rollout:
            per_config, fresh = (1, 1) if args.quick else (PER_CONFIG, FRESH_PER_CONFIG)

            def add(method, seed, run_path):
                records.append({**record(Run(run_path), task_name, method, seed, args),
                                **validated_pick(Run(run_path), rollout, scn, seed, per_config, fresh)})

            asked = {(m, s) for m in args.method_list for s in range(args.first_seed, args.first_seed + args.seeds)}
            for method, seed, run_path in finished_runs(args.out, task_name):
                if (method, seed) not in asked:
                    add(method, seed, run_path)
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                for method in args.method_list:
                    run_path = args.out / "runs" / task_name / method / f"seed-{seed}"
                    started = time.monotonic()
                    run_one(rollout, scn, task, method, seed, args, run_path)
                    add(method, seed, run_path)
                    write()
                    print(f"  {method} seed {seed}: {time.monotonic() - started:.0f} s", flush=True)
    return kept + with_hypervolumes(records)


def report(rows: list[dict]) -> str:
    """Median [quartiles] of the final hypervolume per task and method, and the two-sided
    Mann-Whitney U p of ours against each other method."""
    from scipy.stats import mannwhitneyu  # lazy: --report only

    lines = ["| task | method | runs | budget x worlds | final hypervolume, median [q1, q3] | p (ours vs it) "
             "| pick's success in fresh worlds, median [min, max] | ask s, median |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    notes = []
    common = {}
    for task in dict.fromkeys(r["task"] for r in rows):
        given = [r for r in rows if r["task"] == task]
        mine = common[task] = on_common_reference(given)
        if mine is not given:
            notes.append(f"{task}: {mine[0]['reference_from']}, {mine[0]['reference']}")
        ours = [r["hypervolume"] for r in mine if r["method"] == OURS]
        for method in dict.fromkeys(r["method"] for r in mine):
            them = [r for r in mine if r["method"] == method]
            hv = np.array([r["hypervolume"] for r in them])
            q1, med, q3 = np.percentile(hv, [25, 50, 75])
            p = "-" if method == OURS or not ours else f"{mannwhitneyu(ours, hv, alternative='two-sided').pvalue:.3g}"
            asks = [s for r in them for s in r["ask_seconds"]]
            picks = [r["pick_fresh_success"] for r in them if r.get("pick_fresh_success") is not None]
            fresh = (f"{100 * np.median(picks):.1f} % [{100 * min(picks):.0f}, {100 * max(picks):.0f}] "
                     f"({them[0]['pick_fresh_worlds']} worlds)") if picks else "-"
            lines.append(f"| {task} | {method} | {len(them)} | {them[0]['budget']} x {them[0]['worlds']} | "
                         f"{med:.4g} [{q1:.4g}, {q3:.4g}] | {p} | {fresh} | "
                         f"{np.median(asks) if asks else float('nan'):.3g} |")
    return "\n".join(lines + [""] * bool(notes) + [f"Final hypervolumes about {n}." for n in notes]
                     + ["", *budget_fractions(common)])


FRACTIONS = (0.25, 0.5, 0.75, 1.0)


def budget_fractions(by_task: dict[str, list[dict]]) -> list[str]:
    """Per task and method, the median hypervolume at 25, 50, 75 and 100 % of the budget
    (each run's history interpolated in evaluations), with the methods ours trails there.
    ``by_task``: each task's rows about one reference (``on_common_reference``); a task with a
    row that has no history about it is said to."""
    lines = ["| task | method | runs | " + " | ".join(f"{100 * f:g} %" for f in FRACTIONS) + " |",
             "| --- | --- | --- | " + " | ".join("---:" for _ in FRACTIONS) + " |"]
    trailing = []
    for task, given in by_task.items():
        if any("hypervolume_history" not in r for r in given):
            trailing.append(f"{task}: a run's directory is gone and its history is about another reference point")
            continue
        medians = {}
        for method in dict.fromkeys(r["method"] for r in given):
            them = [r for r in given if r["method"] == method]
            at = np.array([[np.interp(f * r["budget"], r["evaluations"], r["hypervolume_history"]) for f in FRACTIONS]
                           for r in them])
            medians[method] = np.median(at, axis=0)
            lines.append(f"| {task} | {method} | {len(them)} | " + " | ".join(f"{v:.4g}" for v in medians[method]) + " |")
        if OURS in medians:
            for k, f in enumerate(FRACTIONS):
                ahead = [m for m, v in medians.items() if m != OURS and v[k] > medians[OURS][k]]
                if ahead:
                    trailing.append(f"{task} at {100 * f:g} %: {OURS}'s median below {', '.join(ahead)}")
    return lines + [""] + (trailing or [f"{OURS}'s median is at least every other method's at every fraction."])


def on_common_reference(rows: list[dict]) -> list[dict]:
    """One task's rows about one reference point. Runs of different seeds come from different
    warm-ups and so, written by separate invocations, about different references: then each
    final hypervolume is computed again from the run's front about the lowest of them (every
    front dominates it; with nested seed sets, the reference of the most warm-ups), and the
    history is computed again from the run's directory, or dropped where that is gone (a new
    list; ``rows`` itself where they agree).
    UserError where a run appears twice."""
    runs = [(r["method"], r["seed"]) for r in rows]
    repeated = sorted({run for run in runs if runs.count(run) > 1})
    if repeated:
        raise UserError(f"--report: the {rows[0]['task']} runs {repeated} appear in more than one line; "
                        "name each results file once")
    references = np.array([r["reference"] for r in rows], dtype=float)
    if (references == references[0]).all():
        return rows
    lowest = references.min(axis=0)  # the objectives are maximized
    stated = f"the lowest of the rows' {len({tuple(x) for x in references})} reference points"
    return [{**r, "reference_from": stated} if np.array_equal(r["reference"], lowest) else
            {**{k: v for k, v in r.items() if k not in ("hypervolume_history", "evaluations")},
             "hypervolume": float(hypervolume(-np.asarray(r["front"], dtype=float), -lowest)),
             **history_about(r, lowest), "reference": lowest.tolist(), "reference_from": stated}
            for r in rows]


def history_about(row: dict, reference: np.ndarray) -> dict:
    """``hypervolume_history`` and ``evaluations`` of the row's run about ``reference``, from
    its run directory's evaluations (relative paths: to the repository); {} where the
    directory is gone or unreadable (then the row has no history)."""
    path = Path(row.get("run_dir", ""))
    path = path if path.is_absolute() else ROOT / path
    try:
        run = Run(path)
        ev = run.evaluations(run.config())
    except (OSError, UserError):
        return {}
    return batch_history(ev.objectives, ev.iteration, reference)


ROW_KEYS = {"task", "method", "seed", "hypervolume", "budget", "worlds", "reference", "front"}  # what report reads


def read_rows(paths: list[Path], source: str = "--report") -> list[dict]:
    """The lines of the JSONL files; UserError naming the file and line that is not a result
    (``source``: where the path came from)."""
    rows = []
    for path in paths:
        try:
            lines = path.read_text().splitlines()
        except OSError as err:
            raise UserError(f"{source} {path}: cannot read it ({err.strerror})") from None
        for number, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError as err:
                raise UserError(f"{source} {path} line {number}: not JSON ({err.msg})") from None
            if not isinstance(row, dict) or not ROW_KEYS <= set(row):
                raise UserError(f"{source} {path} line {number}: not a task_optimizers result")
            rows.append(row)
    return rows


def main(argv=None) -> list[dict]:
    args = parse(argv)
    rows = read_rows(args.report) if args.report else benchmark(args)
    print(report(rows))
    return rows


if __name__ == "__main__":
    try:
        main()
    except UserError as err:  # bad input (a flag, a file, a missing extra): one line, exit 2
        print(f"task_optimizers.py: error: {err}", file=sys.stderr)
        sys.exit(2)
