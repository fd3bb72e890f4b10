"""What the explore page shows, as plain data: the runs in a directory, their evaluations, their
Pareto fronts and hypervolume curves, a pick by limits and the export of a solution.

Every document is JSON-ready: numbers are floats or None (a NaN or an infinity is not JSON).
A point is named by ``(run, index)``: the position of its run in :func:`runs_in` and its row in
that run's ``evaluations.csv`` (append-only, so the name stays valid while a run trains on); a
Pareto solution also has ``k``, its row in ``pareto.csv`` (the number ``select --pick`` takes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mjxskill._files import is_regular
from mjxskill.errors import RunError
from mjxskill.evaluation.selection import choose
from mjxskill.evaluation.validation import validated_union
from mjxskill.runs.run_dir import CONFIG, PARETO, Evaluations, Run, RunConfig
from mjxskill.runs.layout import OPTIMIZER_RUNS, RANDOM_RUNS, directory_kind
from mjxskill.training.front import hypervolume_history, reference_from


@dataclass(frozen=True)
class RunEntry:
    """One run shown on the page: ``label`` names it in the legend ("seed 3")."""

    label: str
    run: Run
    config: RunConfig

    def evaluations(self) -> Evaluations:
        return self.run.evaluations(self.config)

    def front(self) -> Evaluations:
        """The rows of pareto.csv (none before the first batch is written)."""
        if not is_regular(self.run.path / PARETO, RunError):
            return Evaluations.empty(len(self.config.parameter_names), len(self.config.objective_names),
                                     self.config.pooled)
        return self.run.pareto(self.config)


def runs_in(path: Path) -> list[RunEntry]:
    """The runs the directory ``path`` holds, in the order the page colours them: the run itself,
    the repetitions of a repeated run (``train --repeats N``: ``seed-<s>/`` sub-runs; the ones
    not yet started are left out), or an experiment's optimizer repetitions and then its random
    searches (``mjxskill.runs.layout`` knows the layouts)."""
    path = Path(path)
    if directory_kind(path) == "experiment":
        entries = []
        for folder, kind in ((OPTIMIZER_RUNS, "optimizer"), (RANDOM_RUNS, "random search")):
            if is_regular(path / folder / CONFIG, RunError):
                entries += [RunEntry(f"{kind} {e.label}", e.run, e.config) for e in _started_runs(path / folder)]
        if not entries:
            raise RunError(f"{path} is an experiment none of whose runs has started (no {OPTIMIZER_RUNS}/seed-*/{CONFIG})")
        return entries
    return _started_runs(path)


def _started_runs(path: Path) -> list[RunEntry]:
    root = Run(path)
    config = root.config()
    if config.repeats == 1:
        return [RunEntry(f"seed {config.seed}", root, config)]
    started = [(sub, sub.config()) for sub in root.sub_runs(config) if is_regular(sub.path / CONFIG, RunError)]
    entries = [RunEntry(f"seed {sub_config.seed}", sub, sub_config) for sub, sub_config in started]
    if not entries:
        raise RunError(f"{root.path} holds {config.repeats} repeated runs but none has started (no seed-*/{CONFIG})")
    return entries


def number(value) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def numbers(values) -> list[float | None]:
    return [number(v) for v in np.ravel(values)]


def run_document(path: Path, entries: list[RunEntry]) -> dict:
    """The task, its parameters (with units and bounds) and objectives, and the runs."""
    config = entries[0].config
    return {
        "path": str(path),
        "task": config.task,
        "goal": config.goal,
        "parameters": [{"name": n, "unit": u, "lower": lo, "upper": hi}
                       for n, u, lo, hi in zip(config.parameter_names, config.parameter_units, *config.bounds)],
        "objectives": list(config.objective_names),
        "worlds": config.worlds,
        "episode_seconds": config.episode_seconds,
        "n_init": config.n_init,
        "runs": [{"run": i, "label": e.label, "path": str(e.run.path), "seed": e.config.seed, "budget": e.config.budget}
                 for i, e in enumerate(entries)],
    }


def _row(ev: Evaluations, i: int) -> dict:
    return {"iteration": int(ev.iteration[i]), "params": numbers(ev.params[i]), "objectives": numbers(ev.objectives[i]),
            "success_rate": number(ev.success_rate[i]),
            # the measured contact force (what --max-force limits) and the commanded one
            "peak_contact_force": number(ev.peak_contact_force[i]), "mean_contact_force": number(ev.mean_contact_force[i]),
            "peak_commanded_force": number(ev.peak_commanded_force[i])}


def evaluation_rows(ev: Evaluations, front: Evaluations) -> np.ndarray:
    """(len(front),) row of ``ev`` that each Pareto row is (pareto.csv copies its rows exactly)."""
    where = {(int(ev.iteration[i]), *ev.params[i].tolist()): i for i in range(len(ev))}
    return np.array([where.get((int(front.iteration[k]), *front.params[k].tolist()), -1) for k in range(len(front))], int)


def front_document(entries: list[RunEntry]) -> dict:
    """The rows of every run's pareto.csv with their values (``/api/front``) and their validation
    success (``validated``: None where the row was not validated, as select lists it)."""
    rows = []
    fronts = [entry.front() for entry in entries]
    for r, (entry, front) in enumerate(zip(entries, fronts)):
        index = evaluation_rows(entry.evaluations(), front)
        rows += [{"run": r, "k": k, "index": int(index[k]), **_row(front, k)} for k in range(len(front))]
    rates = validated_union((e.run, f) for e, f in zip(entries, fronts))[0]
    for i, row in enumerate(rows):
        row["validated"] = None if rates is None or np.isnan(rates[i]) else float(rates[i])
    return {"columns": entries[0].config.columns(), "rows": rows}


def evaluations_document(entries: list[RunEntry]) -> dict:
    """Every evaluation of every run, with the Pareto row it is (``k``, else None)."""
    rows = []
    for r, entry in enumerate(entries):
        ev = entry.evaluations()
        k_of = {int(i): k for k, i in enumerate(evaluation_rows(ev, entry.front()))}
        rows += [{"run": r, "index": i, "k": k_of.get(i), **_row(ev, i)} for i in range(len(ev))]
    return {"columns": entries[0].config.columns(), "rows": rows}


def hypervolume_document(entries: list[RunEntry]) -> dict:
    """Each run's hypervolume after each batch (empty before its warm-up is complete)."""
    curves = []
    for r, entry in enumerate(entries):
        ev = entry.evaluations()
        ref = reference_from(entry.run, entry.config, ev, store=False) if len(ev) else None
        done, hv = hypervolume_history(ev, ref) if ref is not None else (np.zeros(0), np.zeros(0))
        curves.append({"run": r, "evaluations": [int(n) for n in done], "hypervolume": numbers(hv)})
    return {"space": "negated objectives (minimized), reference fixed after the warm-up", "curves": curves}


def point(entries: list[RunEntry], run: int, index: int) -> tuple[RunEntry, Evaluations]:
    """The run entry and the one-row Evaluations of point ``(run, index)``."""
    if not 0 <= run < len(entries):
        raise RunError(f"run {run}: this directory holds runs 0-{len(entries) - 1}")
    ev = entries[run].evaluations()
    if not 0 <= index < len(ev):
        raise RunError(f"evaluation {index}: run {run} has rows 0-{len(ev) - 1}")
    return entries[run], ev.take(slice(index, index + 1))


def choose_document(entries: list[RunEntry], max_force: float | None, min_success: float | None) -> dict:
    """The Pareto solution ``select`` picks for these limits among every run's front (a
    validated one first where the runs' picks were validated)."""
    fronts = [e.front() for e in entries]
    owners = np.concatenate([np.full(len(f), r) for r, f in enumerate(fronts)])
    union = fronts[0]
    for f in fronts[1:]:
        union = union.concat(f)
    if len(union) == 0:
        raise RunError("the Pareto front is empty (no evaluations yet)")
    seconds: list[float] = []
    rates, _ = validated_union(((e.run, f) for e, f in zip(entries, fronts)), seconds=seconds)  # as select reads them
    j = choose(union, max_force, min_success, rates, seconds or None)
    run = int(owners[j])
    return {"run": run, "k": int(j - np.flatnonzero(owners == run)[0])}
