"""The tables of benchmarks/NOTES.md section 25 from this folder's files.

Each lever's folder holds the JSONL that ``benchmarks/task_optimizers.py --tasks push --methods
mjxskill.gp --seeds 10 --budget 102 --optimizer-option ... --out FOLDER`` wrote, and its runs'
``evaluations.csv`` (the planned task's files, the same for every lever: in ``given/runs/push/``); the
baseline and qLogNEHVI are the committed 200 x 7 runs (their first 102
rows: the baseline at budget 102 reproduced their history exactly). Run from the repository
root: ``python benchmarks/results/2026-12-07/push_first_batches/summarize.py``.
"""

import csv
import json
from pathlib import Path

import numpy as np
from scipy.stats import wilcoxon

from mjxskill.gp import hypervolume

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[3]
COMMITTED = ROOT / "benchmarks/results/task_optimizers-200x7"
SOURCES = {"baseline": (COMMITTED / "task_optimizers.jsonl", "mjxskill.gp", COMMITTED / "runs/push/mjxskill.gp"),
           **{lever: (HERE / lever / "task_optimizers.jsonl", "mjxskill.gp", HERE / lever / "runs/push/mjxskill.gp")
              for lever in ("given", "nosingle", "exact", "search", "draws", "dimscaled", "dimscaled_draws", "draws_steps60", "draws_restarts5", "draws_ndraws8",
                                "small_noise", "small_noise_draws", "unit_outputscale_draws")},
           "qLogNEHVI": (ROOT / "benchmarks/results/task_optimizers-200x7-botorch/task_optimizers.jsonl",
                         "botorch-qlognehvi",
                         ROOT / "benchmarks/results/task_optimizers-200x7-botorch/runs/push/botorch-qlognehvi")}
POINTS = (54, 60, 72, 84, 100)


def rows(path: Path, method: str) -> dict:
    return {r["seed"]: r for r in map(json.loads, path.read_text().splitlines())
            if r["task"] == "push" and r["method"] == method}


def at(row: dict, evaluations: int) -> float:
    return float(np.interp(evaluations, row["evaluations"], row["hypervolume_history"]))


def element_gains(runs: Path, reference: np.ndarray) -> np.ndarray:
    """(seeds, 3 batches, 6 elements + the batch) hypervolume gain of each first-batches
    element alone, and of the whole batch, over the rows before its batch."""
    out = []
    for seed in range(10):
        with open(runs / f"seed-{seed}" / "evaluations.csv") as fh:
            y = -np.array([[float(r["objective_success"]), float(r["objective_applied_force"])]
                           for r in csv.DictReader(fh)])
        per_seed = []
        for batch in range(3):
            n = 48 + 6 * batch
            base = hypervolume(y[:n], reference)
            per_seed.append([hypervolume(np.vstack([y[:n], y[n + k:n + k + 1]]), reference) - base for k in range(6)]
                            + [hypervolume(y[:n + 6], reference) - base])
        out.append(per_seed)
    return np.array(out)


def main():
    loaded = {name: rows(path, method) for name, (path, method, _) in SOURCES.items() if path.is_file()}
    print("| evaluations | " + " | ".join(map(str, POINTS)) + " |")
    for name, runs in loaded.items():
        print(f"| {name} ({len(runs)} seeds) | " + " | ".join(
            f"{np.median([at(r, e) for r in runs.values()]) / 1e3:.2f}" for e in POINTS) + " |")
    print()
    base = loaded["baseline"]
    for name, runs in loaded.items():
        if name == "baseline":
            continue
        seeds = sorted(set(runs) & set(base))
        cells = []
        for e in POINTS:
            d = np.array([at(runs[s], e) - at(base[s], e) for s in seeds])
            p = wilcoxon(d).pvalue if np.any(d != 0) else 1.0
            cells.append(f"{np.median(d):+.0f} ({(d > 0).sum()}/{(d < 0).sum()}, p {p:.2f})")
        print(f"| {name} vs baseline | " + " | ".join(cells) + " |")
    print()
    reference = -np.asarray(next(iter(base.values()))["reference"])
    for name, (_, _, runs) in SOURCES.items():
        if not (runs / "seed-9" / "evaluations.csv").is_file():
            continue
        g = element_gains(runs, reference)
        print(f"{name}: mean gain per element of batches 1-3 (then the batch): "
              + "; ".join(" ".join(f"{v:.0f}" for v in g[:, b].mean(0)) for b in range(3))
              + "; share of elements adding to the front, by position: "
              + " ".join(f"{v:.2f}" for v in (g[:, :, :6] > 0).mean((0, 1))))


if __name__ == "__main__":
    main()
