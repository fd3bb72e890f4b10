"""Parameter priors (piBO) in mjxskill.gp: hypervolume after 20 and 40 evaluations and at the
full budget, without a prior, with a good prior and with a misleading one.

Problems: BraninCurrin and ZDT1 (d = 6) from ``benchmarks/mobo_quality.py`` (imported), ZDT1 at
its standard d = 30 (the default, ``--problems tuning``); issue 44's held-out problems
(``--problems held-out``, RESULTS.md "The tuning set and the held-out set"; reported only,
never tuned on): ZDT2 (d = 6), CarSideImpact (d = 7, m = 4), DTLZ2 (d = 6, m = 4) and the noisy
ZDT3 (d = 6; the run sees noisy observations, every score is of the noiseless values); and,
with ``--push``, the push task through the training loop's own functions (native engine, full
12 s episodes, few worlds). Budget ``--budget`` (default 60) in batches of ``--batch`` (5)
after ``--init`` (10) warm-up points; the optimizer's defaults otherwise (pibo_beta 2,
prior_share 0.5: half the warm-up from the prior; ``--option pibo_beta=10`` as measured
before the default was lowered).

The priors, per problem, each one Gaussian per dimension with a standard deviation of
``--std-fraction`` (0.15) of the range, truncated to the bounds:

* good: centred on a known Pareto-optimal point. BraninCurrin: the Pareto-optimal point of a
  401 x 401 grid closest (normalized objectives) to the ideal point; ZDT1: x1 = 0.5, x2..d = 0
  (its Pareto set is x2..d = 0). Push: the scenario's operator set operator_a (a hand-written
  push into the goal corner; illustrative, not a verified optimum).
* transfer: what ``train --prior-from`` builds from an earlier run's front, one component per
  Pareto solution (std ``PRIOR_FROM_STD_FRACTION`` of the range), here 8 Pareto-optimal points
  spread evenly along the front's length (ZDT1: x1 = 0, 1/7, .., 1, x2..d = 0; BraninCurrin: from the
  401 x 401 grid's front). Push: not measured.
* misleading: centred on a region of poor objectives. BraninCurrin: (0.1, 0.1) (both objectives
  near their worst: printed with their percentile among uniform draws); ZDT1: x1 = 0.5,
  x2..d = 1 (g = 10, the worst); push: every offset at +0.25 m (the tool starts and ends far
  from the prism and the goal).

The held-out problems' priors (their objectives and percentiles are printed at the start):

* ZDT2: as ZDT1's (good x1 = 0.5, x2..6 = 0 on its Pareto set; misleading x2..6 = 1, g = 10;
  transfer the same 8 points).
* ZDT3, noisy: good x2..6 = 0 and x1 = 0.4473, the point of its front (2 M samples of f1)
  nearest the ideal point in normalized objectives (x1 = 0.5 with g = 1 lies between two
  pieces of its front, dominated); misleading x1 = 0.5, x2..6 = 1 (g = 10).
* DTLZ2 (m = 4): good every coordinate 0.5 (x4..6 = 0.5 is its Pareto set, the angles
  x1..3 at the middle); misleading x1..3 = 0.5, x4..6 = 1 (g = 0.75, the worst: objectives
  worse than 80-88 % of uniform draws).
* CarSideImpact: from 50,000 uniform draws (seed 0): good, the point of their non-dominated
  set nearest the ideal point in objectives normalized over that set; misleading, the draw
  whose best objective percentile among the draws is the worst (about 72 % in every one of
  the four conflicting objectives).
* transfer is defined on ZDT2 only of them (not run in the held-out check).

The reference point is inferred from the warm-up (as a robot run has it) unless
``--given-ref`` gives the optimizer the problem's.

The report (printed at the end, or with ``--report`` from saved files, several merged by
seed) gives per setting and checkpoint the hypervolume about the problem's reference point and
the regret a run without a prior would report: the share (%) of the whole front's
hypervolume missed about the reference point that the same seed's no-prior run infers from
its warm-up (``mobo_quality.py``'s own-reference regret, here one reference for every setting
of a seed, so that the settings compare), or about the problem's reference with
``--given-ref``. Each setting is compared with no prior by a two-sided Mann-Whitney U test on
the regret (push: on the hypervolume).

The log hypervolume gap (issue 44's must-hold 4 is stated in it): log10(HV* - HV), the
hypervolume the whole Pareto front dominates about a reference less the run's about the same
reference, per seed and checkpoint (BoTorch's "log hypervolume difference"). Printed about
the regret's reference (the same seed's no-prior run's inferred one: the gap a run reports;
HV* = ``front_hv`` of it; the regret is this gap as a share of HV*), and about the
problem's reference (HV* = ``max_hv``; the only one for CarSideImpact, whose front has no
closed form). "d decades" against no prior: the median over seeds of a setting's log10 gap
less no prior's, at the same checkpoint (+0.15: a gap 10^0.15 = 1.41 times no prior's); p:
two-sided Mann-Whitney U on the gaps.

    python benchmarks/mobo_priors.py --seeds 10 --save prior-runs.json
    python benchmarks/mobo_priors.py --seeds 10 --problems held-out --settings none,good,misleading --save held-out.json
    python benchmarks/mobo_priors.py --seeds 5 --push --push-only --push-worlds 3 --push-budget 36
    python benchmarks/mobo_priors.py --report prior-runs.json more-seeds.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.dirname(__file__))
import mjxskill  # noqa: E402,F401

from mjxskill.gp import Prior, hypervolume, minimize  # noqa: E402
from mjxskill.gp.hypervolume_scalarization import warmup_reference  # noqa: E402
from mjxskill.training.priors import PRIOR_FROM_STD_FRACTION  # noqa: E402
from mobo_quality import HELD_OUT, PROBLEMS, branin_currin, observer, parse_options, zdt3_front  # noqa: E402

SETTINGS = ("none", "good", "misleading", "transfer")
TRANSFER_COMPONENTS = 8  # Pareto solutions an earlier run hands on (a run's front holds 5-15)
# ZDT1 at its standard dimension (Zitzler et al. 2000) beside mobo_quality's d = 6: with 20-40
# evaluations in 6 dimensions the optimizer alone is at 98-99.8 % of the maximum, which leaves a
# prior nothing to show; in 30 it is not, as on a robot cell with more parameters than a budget
# of 20-40 episodes can explore.
GP_PROBLEMS_BY_NAME = {**PROBLEMS, "ZDT1 (d=30)": dict(PROBLEMS["ZDT1 (d=6)"], d=30)}
GP_PROBLEMS = ("BraninCurrin", "ZDT1 (d=6)", "ZDT1 (d=30)")
# Issue 44's held-out problems (RESULTS.md, "The tuning set and the held-out set"): reported only,
# never tuned on. ``--problems held-out`` names them all.
HELD_OUT_PROBLEMS = tuple(HELD_OUT)
PROBLEM_GROUPS = {"held-out": HELD_OUT_PROBLEMS, "tuning": GP_PROBLEMS}


def code_version() -> str:
    """The commit the runs come from (with " + changes" where the tree differs from it), or
    "unknown" outside a git checkout: results of different code must not be taken for one."""
    import subprocess

    here = os.path.dirname(os.path.abspath(__file__))
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=here, capture_output=True,
                               text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return commit + (" + changes" if dirty else "")


def nearest_ideal(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The Pareto-optimal point of ``x`` nearest the ideal point (normalized objectives ``y``)."""
    norm = (y - y.min(0)) / (y.max(0) - y.min(0))
    return x[np.argmin(np.linalg.norm(norm, axis=1))]


def branin_currin_pareto_set(n: int = 401) -> tuple[np.ndarray, np.ndarray]:
    """The Pareto-optimal points of an n x n grid and their objectives, by the first objective."""
    g = np.linspace(0.0, 1.0, n)
    x = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    x[:, 1] = np.maximum(x[:, 1], 1e-9)  # Currin divides by x2
    y = branin_currin(x)
    order = np.argsort(y[:, 0], kind="stable")
    best2, front = np.inf, []
    for i in order:  # a sweep by the first objective: non-dominated iff it improves the second
        if y[i, 1] < best2:
            best2 = y[i, 1]
            front.append(i)
    return x[front], y[front]


def spread_along_front(x: np.ndarray, y: np.ndarray, k: int) -> np.ndarray:
    """k of the Pareto-optimal points ``x`` (ordered by the first objective) evenly spaced along
    the front's length in normalized objectives."""
    u = (y - y.min(0)) / (y.max(0) - y.min(0))
    length = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(u, axis=0), axis=1))]
    return x[[int(np.argmin(np.abs(length - t))) for t in np.linspace(0.0, length[-1], k)]]


def non_dominated(y: np.ndarray) -> np.ndarray:
    """Indices of the non-dominated rows of ``y`` (minimization), by an archive swept in the
    order of the normalized objectives' sum (a row can only be dominated by one of smaller sum):
    fast for the 10^4-10^5 draws of a dense sample whose front holds a few thousand."""
    u = (y - y.min(0)) / np.where(y.max(0) > y.min(0), y.max(0) - y.min(0), 1.0)
    keep: list = []
    archive = np.zeros((0, y.shape[1]))
    for i in np.argsort(u.sum(1), kind="stable"):
        if len(archive) and np.any(np.all(archive <= y[i], 1) & np.any(archive < y[i], 1)):
            continue
        keep.append(i)
        archive = np.vstack([archive, y[i]])
    return np.asarray(keep)


CAR_SIDE_IMPACT_DRAWS = 50_000  # uniform draws of the dense sample (seed 0): its front holds about 1,300 points


def car_side_impact_points() -> tuple[np.ndarray, np.ndarray]:
    """CarSideImpact's good and misleading prior centres, from ``CAR_SIDE_IMPACT_DRAWS`` uniform
    draws (seed 0): the point of their non-dominated set nearest the ideal point in objectives
    normalized over that set, and the draw whose best objective percentile among the draws is
    the worst (four conflicting objectives: no draw is bad in all of them beyond ~73 %)."""
    problem = GP_PROBLEMS_BY_NAME["CarSideImpact"]
    x = np.random.default_rng(0).random((CAR_SIDE_IMPACT_DRAWS, problem["d"]))
    y = problem["f"](x)
    front = non_dominated(y)
    percentile = np.argsort(np.argsort(y, axis=0), axis=0) / len(y) * 100.0
    return nearest_ideal(x[front], y[front]), x[np.argmax(percentile.min(axis=1))]


def gp_priors(name: str, d: int, std_fraction: float) -> dict:
    """The priors of a GP problem (module docstring): {setting: Prior or None}; a setting not
    defined for the problem (transfer on most held-out problems) is absent."""
    transfer = None
    if name == "BraninCurrin":
        pareto_set = branin_currin_pareto_set()  # a 401 x 401 grid: once for both priors
        good, bad = nearest_ideal(*pareto_set), np.array([0.1, 0.1])
        transfer = spread_along_front(*pareto_set, TRANSFER_COMPONENTS)
    elif name.startswith(("ZDT1", "ZDT2")):  # the Pareto set is x2..d = 0, x1 anywhere
        good, bad = np.r_[0.5, np.zeros(d - 1)], np.r_[0.5, np.ones(d - 1)]
        transfer = np.c_[np.linspace(0.0, 1.0, TRANSFER_COMPONENTS), np.zeros((TRANSFER_COMPONENTS, d - 1))]
    elif name.startswith("ZDT3"):  # x2..d = 0 and x1 on one of the five pieces of the front
        front = zdt3_front()
        good = np.r_[nearest_ideal(front[:, :1], front)[0], np.zeros(d - 1)]
        bad = np.r_[0.5, np.ones(d - 1)]
    elif name.startswith("DTLZ2"):  # the Pareto set is x_m..d = 0.5, the first m - 1 anywhere
        m = len(GP_PROBLEMS_BY_NAME[name]["ref"])
        good, bad = np.full(d, 0.5), np.r_[np.full(m - 1, 0.5), np.ones(d - m + 1)]
    elif name == "CarSideImpact":
        good, bad = car_side_impact_points()
    else:
        raise ValueError(f"no priors defined for {name!r}")
    priors = {"none": None, "good": Prior(mean=good, std=std_fraction), "misleading": Prior(mean=bad, std=std_fraction)}
    if transfer is not None:
        priors["transfer"] = Prior(mean=transfer, std=PRIOR_FROM_STD_FRACTION)
    return priors


def percentile_of(problem, point, n=100_000) -> list:
    """Each objective's percentile at ``point`` among uniform draws (100: worse than all)."""
    y = problem["f"](np.random.default_rng(0).random((n, problem["d"])))
    at = problem["f"](np.asarray(point)[None])[0]
    return [float(np.mean(y[:, i] < at[i]) * 100) for i in range(len(at))]


def run_gp(problem, prior, seed, args, options) -> np.ndarray:
    """The objectives of a run's points in evaluation order: noiseless, also where the run saw
    noisy observations (``mobo_quality.observer``: ZDT3, noisy), as ``mobo_quality.py`` scores."""
    bounds = np.stack([np.zeros(problem["d"]), np.ones(problem["d"])])
    res = minimize(observer(problem, seed), bounds, budget=args.budget, batch_size=args.batch, n_init=args.init, seed=seed,
                   prior=prior, acquisition=options,  # not **options: its "prior" is the GP's
                   ref_point=problem["ref"] if args.given_ref else None)
    return problem["f"](res.X)


def checkpoints_of(budget: int, marks=(20, 40)) -> list:
    """The evaluation counts a report reads: the marks within the budget, and the budget."""
    return sorted({c for c in (*marks, budget) if c <= budget})


def hv_at(y: np.ndarray, ref, checkpoints) -> list:
    return [float(hypervolume(y[:c], ref)) for c in checkpoints]


def quartiles(values, digits: int = 2) -> str:
    q1, med, q3 = np.percentile(values, [25, 50, 75])
    return f"{med:,.{digits}f} [{q1:,.{digits}f}, {q3:,.{digits}f}]"


# -- the push task ----------------------------------------------------------------------------
def push_priors(task, std_fraction: float) -> dict:
    lo, hi = np.asarray(task.bounds)
    std = std_fraction * (hi - lo)
    good = np.asarray(task.manual_parameters["operator_a"])
    bad = np.clip(np.full(len(lo), 0.25), lo, hi)
    return {"none": None, "good": {"source": "operator_a", "mean": [good.tolist()], "std": [std.tolist()], "weights": [1.0]},
            "misleading": {"source": "offsets +0.25", "mean": [bad.tolist()], "std": [std.tolist()], "weights": [1.0]}}


def run_push(rollout, task, scn, prior, seed, args, options) -> np.ndarray:
    """One training run of the push task with the training loop's functions (a temporary run
    directory); returns the objectives (n, 2), larger is better, in evaluation order."""
    from mjxskill.training.loop import rollout_evaluator, train
    from mjxskill.runs.run_dir import Run, RunConfig

    config = RunConfig(task=scn.name, scenario="push", goal=task.goal, parameter_names=tuple(task.parameter_names),
                       parameter_units=tuple(task.parameter_units),
                       bounds=(tuple(map(float, task.bounds[0])), tuple(map(float, task.bounds[1]))),
                       objective_names=tuple(scn.objective_names), budget=args.push_budget, batch_size=args.push_batch,
                       n_init=args.push_init, worlds=args.push_worlds, seed=seed, episode_seconds=args.push_seconds,
                       engine="native", optimizer_options=options, prior=prior)
    with tempfile.TemporaryDirectory() as tmp:
        run = Run(os.path.join(tmp, "run"))
        from mjxskill.task import planning_texts

        run.create(config, scn.source, planning_texts(task))
        ev = train(run, config, rollout_evaluator(rollout, config.batch_size, seed))
    return np.asarray(ev.objectives, np.float64)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=0,
                    help="seeds first-seed .. first-seed + seeds - 1 (to add seeds to an earlier run)")
    ap.add_argument("--budget", type=int, default=60)
    ap.add_argument("--batch", type=int, default=5)
    ap.add_argument("--init", type=int, default=10)
    ap.add_argument("--std-fraction", type=float, default=0.15)
    ap.add_argument("--problems", nargs="*", default=list(GP_PROBLEMS), choices=[*GP_PROBLEMS_BY_NAME, *PROBLEM_GROUPS],
                    metavar="PROBLEM", help=f"any of: {', '.join(GP_PROBLEMS_BY_NAME)}; or a group: held-out "
                    f"({', '.join(HELD_OUT_PROBLEMS)}), tuning ({', '.join(GP_PROBLEMS)}); default: tuning")
    ap.add_argument("--settings", default=",".join(SETTINGS))
    ap.add_argument("--given-ref", action="store_true",
                    help="give the optimizer the problem's reference point (default: inferred from the warm-up, as a robot run has it)")
    ap.add_argument("--option", action="append", default=[], help="acquisition setting KEY=VALUE of mjxskill.gp")
    ap.add_argument("--push", action="store_true", help="also the push task (slow: physics)")
    ap.add_argument("--push-only", action="store_true", help="only the push task")
    ap.add_argument("--push-seeds", type=int, default=None, help="seeds of the push task (default --seeds)")
    ap.add_argument("--push-worlds", type=int, default=3)
    ap.add_argument("--push-budget", type=int, default=36)
    ap.add_argument("--push-batch", type=int, default=6)
    ap.add_argument("--push-init", type=int, default=12)
    ap.add_argument("--push-seconds", type=float, default=12.0, help="episode length (12: the scenario's full episodes)")
    ap.add_argument("--save", help="write the raw results (objective values of every run) as JSON")
    ap.add_argument("--report", nargs="+", metavar="FILE",
                    help="run nothing: print the report of runs saved with --save (several files merged by seed)")
    args = ap.parse_args(argv)
    if args.report:
        try:
            raw = load_saved(args.report)
        except (OSError, ValueError) as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
        report(raw)
        return 0
    options = parse_options(args.option)
    args.problems = list(dict.fromkeys(p for name in args.problems for p in PROBLEM_GROUPS.get(name, (name,))))
    settings = [s for s in args.settings.split(",") if s]
    checkpoints = checkpoints_of(args.budget)
    started = time.monotonic()
    print(f"load average at start: {' '.join(f'{v:.2f}' for v in os.getloadavg())} ({os.cpu_count()} cores)")
    print(f"priors: one truncated Gaussian per dimension, std {args.std_fraction:g} x range; acquisition options "
          f"{options or 'defaults'} (pibo_beta 2, prior_share 0.5 unless set)")
    if not args.push_only:
        print(f"GP problems: budget {args.budget} = {args.init} warm-up + batches of {args.batch}; seeds {args.first_seed}..{args.first_seed + args.seeds - 1}")
    raw = {"args": vars(args), "checkpoints": checkpoints, "code": code_version(), "problems": {}}
    for name in [] if args.push_only else args.problems:
        problem = GP_PROBLEMS_BY_NAME[name]
        priors = gp_priors(name, problem["d"], args.std_fraction)
        print(f"\n{name} (ref {problem['ref']}, max hypervolume {problem['max_hv']}):")
        for kind in ("good", "misleading"):
            mean = np.asarray(priors[kind].mean[0])
            print(f"  {kind} prior centred on {np.round(mean, 4).tolist()}: objectives "
                  f"{np.round(problem['f'](mean[None])[0], 3).tolist()}, percentile among uniform draws "
                  f"{np.round(percentile_of(problem, mean), 1).tolist()} (0: better than all)")
        entry = raw["problems"][name] = {"ref": problem["ref"], "max_hv": problem["max_hv"], "runs": {}}
        for kind in [k for k in settings if k in priors]:  # transfer: not defined on every problem
            hvs, secs = [], []
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                t0 = time.monotonic()
                y = run_gp(problem, priors[kind], seed, args, options)
                secs.append(time.monotonic() - t0)
                hvs.append(hv_at(y, problem["ref"], checkpoints))
                entry["runs"].setdefault(kind, []).append({"seed": seed, "y": y.tolist(), "hv": hvs[-1], "seconds": secs[-1]})
                print(f"    {name} / {kind} seed {seed}: {secs[-1]:.0f} s, load {os.getloadavg()[0]:.2f}", file=sys.stderr, flush=True)
            hv = np.asarray(hvs)
            cells = ", ".join(f"{c}: {quartiles(hv[:, i])}" for i, c in enumerate(checkpoints))
            print(f"  {kind:<10} hypervolume median [q1, q3] at {cells}  ({np.mean(secs):.0f} s/run)", flush=True)
            if args.save:  # what is done so far, should the rest not finish
                with open(args.save, "w") as fh:
                    json.dump(raw, fh)
    if args.push or args.push_only:
        _push(args, options, settings, raw)
    print(f"\nload average at end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}; {time.monotonic() - started:.0f} s")
    raw["load_end"] = os.getloadavg()
    if args.save:
        with open(args.save, "w") as fh:
            json.dump(raw, fh)
    report(raw)
    return 0


def _push(args, options, settings, raw) -> None:
    from mjxskill.engine.build import build_rollout
    from mjxskill.scenario import load_scenario
    from mjxskill.task import plan_task

    scn = load_scenario("push")
    task = plan_task(scn)
    priors = push_priors(task, args.std_fraction)
    seeds = args.seeds if args.push_seeds is None else args.push_seeds
    checkpoints = checkpoints_of(args.push_budget, marks=(20,))
    print(f"\npush: native engine, {args.push_worlds} worlds, {args.push_seconds:g} s episodes, budget {args.push_budget} "
          f"= {args.push_init} warm-up + batches of {args.push_batch}, seeds {args.first_seed}..{args.first_seed + seeds - 1}; good prior: operator_a "
          f"{np.round(priors['good']['mean'][0], 3).tolist()}, misleading: offsets +0.25 m")
    rollout = build_rollout(scn, task, "native", worlds=args.push_worlds, episode_seconds=args.push_seconds)
    runs = {}
    try:
        for kind in [k for k in settings if k in priors]:  # no earlier push run to transfer from
            for seed in range(args.first_seed, args.first_seed + seeds):
                t0 = time.monotonic()
                y = run_push(rollout, task, scn, priors[kind], seed, args, options)
                runs.setdefault(kind, []).append({"seed": seed, "y": y.tolist(), "seconds": time.monotonic() - t0})
                print(f"  {kind} seed {seed}: {time.monotonic() - t0:.0f} s", flush=True)
    finally:
        getattr(rollout, "close", lambda: None)()
    ref, hv = push_hypervolumes(runs, checkpoints)
    for kind, rs in runs.items():  # kept in the file beside the runs (the report at the end prints them)
        for r, h in zip(rs, hv[kind]):
            r["hv"] = h.tolist()
    raw["problems"]["push"] = {"ref_rewards": (-ref).tolist(), "runs": runs}


# -- the report -------------------------------------------------------------------------------
# Arguments that must agree for runs from several files to be merged: they set what a run is.
_SAME_GP = ("budget", "batch", "init", "std_fraction", "given_ref", "option")
_SAME_PUSH = ("push_worlds", "push_budget", "push_batch", "push_init", "push_seconds", "std_fraction", "option")


def load_saved(paths) -> dict:
    """Merge files written by ``--save`` into one raw result: the runs of each problem and
    setting, by seed (a seed saved twice with the same values is kept once). ValueError
    (naming the file and what is wrong) for a file that is not such a result, for settings
    that differ between files, or for a seed saved twice with different values."""
    merged: dict = {"problems": {}}
    first: dict = {}
    for path in paths:
        try:
            with open(path) as fh:
                raw = json.load(fh)
        except json.JSONDecodeError as e:
            raise ValueError(f"{path}: not JSON ({e})") from None
        if not isinstance(raw, dict) or not isinstance(raw.get("args"), dict) or not isinstance(raw.get("problems"), dict):
            raise ValueError(f"{path}: not a result of mobo_priors.py --save (expected keys 'args' and 'problems')")
        for name, entry in raw["problems"].items():
            if name != "push" and name not in GP_PROBLEMS_BY_NAME:
                raise ValueError(f"{path}: unknown problem {name!r} (known: {', '.join(GP_PROBLEMS_BY_NAME)}, push)")
            if not isinstance(entry, dict) or not isinstance(entry.get("runs"), dict):
                raise ValueError(f"{path}: problem {name!r} has no 'runs'")
            keys = _SAME_PUSH if name == "push" else _SAME_GP
            here = {k: raw["args"].get(k) for k in keys}
            there = first.setdefault(name, (path, here))
            for k in keys:
                if here[k] != there[1][k]:
                    raise ValueError(f"{path}: problem {name!r} was run with {k} = {here[k]!r}, "
                                     f"but {there[0]} with {there[1][k]!r}; runs of different settings do not merge")
            target = merged["problems"].setdefault(name, {"args": here, "runs": {}, "code": []})
            code = raw.get("code", "not recorded")
            if code not in target["code"]:
                target["code"].append(code)
            for kind, runs in entry["runs"].items():
                have = target["runs"].setdefault(kind, [])
                seeds = {r["seed"]: r["y"] for r in have}
                for i, r in enumerate(runs):
                    if not isinstance(r, dict) or not isinstance(r.get("seed"), int) or not isinstance(r.get("y"), list):
                        raise ValueError(f"{path}: {name} / {kind}, run {i}: expected 'seed' (an integer) and 'y' (a list)")
                    y = np.asarray(r["y"], np.float64)
                    if y.ndim != 2 or len(y) == 0:
                        raise ValueError(f"{path}: {name} / {kind}, seed {r['seed']}: 'y' is not an (n, m) table")
                    if r["seed"] in seeds:  # a run reproduced (they are deterministic per seed) is kept once
                        if not np.array_equal(seeds[r["seed"]], y):
                            raise ValueError(f"{path}: {name} / {kind}, seed {r['seed']} is saved twice, with different values")
                        continue
                    seeds[r["seed"]] = y
                    have.append({"seed": r["seed"], "y": y})
    return merged


def mann_whitney(a, b) -> float:
    from scipy.stats import mannwhitneyu

    return float(mannwhitneyu(a, b, alternative="two-sided").pvalue)


def report(raw) -> dict:
    """Print, per problem and setting, the hypervolume and (GP problems) the regret at each
    checkpoint, median [q1, q3], and Mann-Whitney p against no prior (module docstring).
    Returns {problem: {setting: {"seeds", "hv" (seeds, checkpoints), "regret" (GP problems,
    seeds with a no-prior run)}}}."""
    out = {}
    for name, entry in raw["problems"].items():
        args = entry.get("args") or raw["args"]
        runs = {kind: sorted(({"seed": r["seed"], "y": np.asarray(r["y"], np.float64)} for r in rs), key=lambda r: r["seed"])
                for kind, rs in entry["runs"].items()}
        codes = entry.get("code", [raw.get("code", "not recorded")])
        if len(codes) > 1:
            print(f"\n{name}: note: these runs come from different code ({'; '.join(codes)})")
        out[name] = (_report_push if name == "push" else _report_gp)(name, args, runs)
    return out


def log_gap(front_hv: float, hv: float) -> float:
    """log10 of the hypervolume gap, the front's hypervolume less the run's about the same
    reference (module docstring); a gap at or below 1e-12 of the front's reads as that."""
    return float(np.log10(max(front_hv - hv, 1e-12 * abs(front_hv))))


def _report_gp(name, args, runs) -> dict:
    problem = GP_PROBLEMS_BY_NAME[name]
    checkpoints = checkpoints_of(args["budget"])
    # The regret's reference: the one the runs report against, the problem's where it was given
    # to them, else the one the same seed's no-prior run inferred from its warm-up.
    own_ref = {r["seed"]: np.asarray(problem["ref"], np.float64) if args["given_ref"] else warmup_reference(r["y"][: args["init"]])
               for r in runs.get("none", [])}
    if problem["front_hv"] is None:  # no front to take a regret about any reference (CarSideImpact)
        own_ref = {}
    front = {seed: problem["front_hv"](ref) for seed, ref in own_ref.items()}
    print(f"\n{name}: hypervolume about {problem['ref']} (max {problem['max_hv']}), and regret (%) about "
          + ("that reference, given to the optimizer" if args["given_ref"] else "the reference the same seed's no-prior run infers"))
    out = {}
    for kind, rs in runs.items():
        hv = np.asarray([hv_at(r["y"], problem["ref"], checkpoints) for r in rs])
        own = [(r, [hypervolume(r["y"][:c], own_ref[r["seed"]]) for c in checkpoints]) for r in rs if r["seed"] in own_ref]
        out[kind] = {"seeds": [r["seed"] for r in rs], "hv": hv,
                     "regret": np.asarray([[100.0 * (1.0 - h / front[r["seed"]]) for h in hs] for r, hs in own]),
                     "log_gap": np.asarray([[log_gap(front[r["seed"]], h) for h in hs] for r, hs in own]),
                     "log_gap_problem_ref": np.asarray([[log_gap(problem["max_hv"], h) for h in row] for row in hv])}
    for kind, o in out.items():
        print(f"  {kind:<10} ({len(o['seeds'])} seeds) hypervolume at "
              + ", ".join(f"{c}: {quartiles(o['hv'][:, i])}" for i, c in enumerate(checkpoints)))
        if len(o["regret"]):
            cells = []
            for i, c in enumerate(checkpoints):
                cell = f"{c}: {quartiles(o['regret'][:, i])}"
                if kind != "none":
                    cell += f" (p {mann_whitney(o['regret'][:, i], out['none']['regret'][:, i]):.3g})"
                cells.append(cell)
            print(f"  {'':<10} regret at " + ", ".join(cells))
        for key, about in (("log_gap", "own reference"), ("log_gap_problem_ref", "the problem's reference")):
            if not len(o[key]):
                continue
            cells = []
            for i, c in enumerate(checkpoints):
                cell = f"{c}: {quartiles(o[key][:, i])}"
                if kind != "none" and "none" in out and len(out["none"][key]):
                    base = out["none"][key][:, i]
                    cell += (f" ({np.median(o[key][:, i]) - np.median(base):+.2f} decades, "
                             f"p {mann_whitney(o[key][:, i], base):.3g})")
                cells.append(cell)
            print(f"  {'':<10} log10 gap ({about}) at " + ", ".join(cells))
    if "none" not in runs:
        print("  (no regret: the file holds no run without a prior to take the reference from)")
    elif problem["front_hv"] is None:
        print("  (no regret about a run's own reference: no front of this problem to measure it by; the log gap is about "
              "the problem's reference and its max_hv)")
    return out


def push_hypervolumes(runs, checkpoints) -> tuple[np.ndarray, dict]:
    """One reference for every run (objectives are maximized, negated here): the worst value of
    each objective over all runs' evaluations, so the hypervolumes of the settings compare.
    Returns (ref, {setting: (seeds, checkpoints) hypervolumes})."""
    ys = {kind: [-np.asarray(r["y"], np.float64) for r in rs] for kind, rs in runs.items()}
    ref = np.concatenate([y for y_kind in ys.values() for y in y_kind]).max(axis=0)
    return ref, {kind: np.asarray([hv_at(y, ref, checkpoints) for y in y_kind]) for kind, y_kind in ys.items()}


def _report_push(name, args, runs) -> dict:
    checkpoints = checkpoints_of(args["push_budget"], marks=(20,))
    ref, hv = push_hypervolumes(runs, checkpoints)
    best = max(float(h.max()) for h in hv.values())
    print(f"\npush: hypervolume in rewards about {np.round(-ref, 3).tolist()} (the worst of every run); the best "
          f"any run reached {best:,.0f}")
    for kind, h in hv.items():
        cells = []
        for i, c in enumerate(checkpoints):
            cell = f"{c}: {quartiles(h[:, i], 0)}, gap {best - np.median(h[:, i]):,.0f}"
            if kind != "none" and "none" in hv:
                cell += f" (p {mann_whitney(h[:, i], hv['none'][:, i]):.3g})"
            cells.append(cell)
        print(f"  {kind:<10} ({len(h)} seeds) " + "; ".join(cells))
    return {kind: {"seeds": [r["seed"] for r in runs[kind]], "hv": h} for kind, h in hv.items()}


if __name__ == "__main__":
    sys.exit(main())
