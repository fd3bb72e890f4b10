"""Multi-objective BO quality: final hypervolume on BraninCurrin and ZDT1 (d = 6).

Budget 6 + 20 x 4 = 86 evaluations (the BoTorch multi-objective tutorial's), >= 10 seeds;
median and quartiles of the final hypervolume for mjxskill.gp, uniform random search with
the same budget and, where BoTorch imports, its qNParEGO (qLogNParEGO when available) with
the same budget. Noiseless problems, minimization.

    python benchmarks/mobo_quality.py --seeds 10 [--botorch] [--write benchmarks/RESULTS.md]
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # see RESULTS.md: threads thrash on 2 cores

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import mjxskill  # noqa: E402,F401

from mjxskill.gp import hypervolume, minimize  # noqa: E402

N_INIT, BATCH, N_BATCHES = 6, 4, 20
BUDGET = N_INIT + BATCH * N_BATCHES


def branin_currin(x: np.ndarray) -> np.ndarray:
    """(q, 2) in [0, 1]^2 -> (q, 2), BoTorch's BraninCurrin (both minimized)."""
    u, v = 15.0 * x[:, 0] - 5.0, 15.0 * x[:, 1]
    t = v - 5.1 / (4 * np.pi**2) * u**2 + 5.0 / np.pi * u - 6.0
    branin = t**2 + 10.0 * (1 - 1 / (8 * np.pi)) * np.cos(u) + 10.0
    a, b = x[:, 0], x[:, 1]
    with np.errstate(divide="ignore"):
        factor = 1.0 - np.exp(-1.0 / (2.0 * b))
    currin = factor * (2300 * a**3 + 1900 * a**2 + 2092 * a + 60) / (100 * a**3 + 500 * a**2 + 4 * a + 20)
    return np.stack([branin, currin], axis=1)


def zdt1(x: np.ndarray) -> np.ndarray:
    f1 = x[:, 0]
    g = 1.0 + 9.0 / (x.shape[1] - 1) * np.sum(x[:, 1:], axis=1)
    return np.stack([f1, g * (1.0 - np.sqrt(f1 / g))], axis=1)


PROBLEMS = {
    "BraninCurrin": dict(f=branin_currin, d=2, ref=[18.0, 6.0], max_hv=59.3601),
    "ZDT1 (d=6)": dict(f=zdt1, d=6, ref=[11.0, 11.0], max_hv=120.6667),
}


def run_ours(problem, seed, **options):
    bounds = np.stack([np.zeros(problem["d"]), np.ones(problem["d"])])
    res = minimize(problem["f"], bounds, budget=BUDGET, batch_size=BATCH, n_init=N_INIT, seed=seed, **options)
    return hypervolume(res.Y, problem["ref"])


def run_random(problem, seed):
    x = np.random.default_rng(10_000 + seed).random((BUDGET, problem["d"]))
    return hypervolume(problem["f"](x), problem["ref"])


def run_botorch(problem, seed):
    import torch
    from botorch.acquisition.multi_objective.parego import qLogNParEGO
    from botorch.fit import fit_gpytorch_mll
    from botorch.models import SingleTaskGP
    from botorch.models.transforms import Normalize, Standardize
    from botorch.optim import optimize_acqf
    from gpytorch.mlls import ExactMarginalLogLikelihood

    torch.manual_seed(seed)
    d = problem["d"]
    bounds = torch.stack([torch.zeros(d), torch.ones(d)]).double()
    f = lambda x: -torch.from_numpy(problem["f"](x.numpy()))  # BoTorch maximizes
    x = torch.rand(N_INIT, d, dtype=torch.double)
    y = f(x)
    for _ in range(N_BATCHES):
        model = SingleTaskGP(x, y, input_transform=Normalize(d), outcome_transform=Standardize(y.shape[-1]))
        fit_gpytorch_mll(ExactMarginalLogLikelihood(model.likelihood, model))
        acq = qLogNParEGO(model=model, X_baseline=x, prune_baseline=True)
        cand, _ = optimize_acqf(acq, bounds=bounds, q=BATCH, num_restarts=10, raw_samples=512, sequential=True,
                                options={"batch_limit": 5, "maxiter": 200})
        x = torch.cat([x, cand])
        y = torch.cat([y, f(cand)])
    return hypervolume(-y.numpy(), problem["ref"])


def summarize(values):
    q1, med, q3 = np.percentile(values, [25, 50, 75])
    return f"{med:.2f} [{q1:.2f}, {q3:.2f}]"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--botorch", action="store_true", help="add BoTorch's qLogNParEGO column")
    ap.add_argument("--write", help="append the table to this markdown file")
    ap.add_argument("--problems", nargs="*", default=list(PROBLEMS))
    ap.add_argument("--option", action="append", default=[], help="MOBOConfig field=value")
    args = ap.parse_args(argv)
    options = {}
    for kv in args.option:
        k, v = kv.split("=")
        options[k] = float(v) if "." in v else int(v)
    rows = []
    for name in args.problems:
        problem = PROBLEMS[name]
        cols = {"mjxskill.gp": [], "random": []}
        if args.botorch:
            cols["BoTorch qLogNParEGO"] = []
        times = {k: 0.0 for k in cols}
        for seed in range(args.seeds):
            for col, fn in (("mjxskill.gp", lambda: run_ours(problem, seed, **options)), ("random", lambda: run_random(problem, seed)),
                            ("BoTorch qLogNParEGO", lambda: run_botorch(problem, seed))):
                if col not in cols:
                    continue
                t = time.perf_counter()
                cols[col].append(fn())
                times[col] += time.perf_counter() - t
            print(name, seed, {k: round(v[-1], 3) for k, v in cols.items()}, flush=True)
        rows.append((name, problem, cols, times))
    lines = [
        f"Measured {datetime.date.today().isoformat()} on the 2-core CPU machine (shared with other jobs), "
        f"budget {N_INIT} + {N_BATCHES} x {BATCH} = {BUDGET}, {args.seeds} seeds, noiseless problems. "
        "Final hypervolume, median [25th, 75th percentile]; wall time is per run.",
        "",
        "| problem | max HV | " + " | ".join(rows[0][2]) + " |",
        "| --- | --- | " + " | ".join("---" for _ in rows[0][2]) + " |",
    ]
    for name, problem, cols, times in rows:
        cells = [f"{summarize(v)} ({times[k] / len(v):.0f} s)" for k, v in cols.items()]
        lines.append(f"| {name} | {problem['max_hv']} | " + " | ".join(cells) + " |")
    if options:
        lines += ["", f"Options: {options}"]
    table = "\n".join(lines)
    print(table)
    if args.write:
        with open(args.write, "a") as fh:
            fh.write(table + "\n\n")


if __name__ == "__main__":
    main()
