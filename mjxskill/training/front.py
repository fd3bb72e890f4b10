"""The Pareto front of a run and its hypervolume.

Hypervolume (progress bar, ``hypervolume.png``): computed in the optimizer's space, the negated
objectives (minimized), with a reference point fixed once the warm-up is complete: per
objective, the worst warm-up value plus 10 % of the warm-up range (1e-9 if the range is 0). It
is stored in ``run_state.json`` and is a pure function of the warm-up rows, so a resumed run
reports the same numbers.
"""

from __future__ import annotations

import numpy as np

from mjxskill.errors import RunError
from mjxskill.gp.pareto import hypervolume, pareto_mask
from mjxskill.runs.run_dir import RUN_STATE, Evaluations, Run, RunConfig, batch_sizes

HV_MARGIN = 0.1  # reference point = worst warm-up value + this fraction of the warm-up range


def hypervolume_reference(warmup_objectives: np.ndarray) -> np.ndarray:
    """(O,) reference point in the minimized space (-objectives) from the (n_init, O) warm-up."""
    z = -np.asarray(warmup_objectives, np.float64)
    z = np.where(np.isfinite(z), z, np.nan)
    worst, best = np.nanmax(z, axis=0), np.nanmin(z, axis=0)
    span = np.where(worst > best, worst - best, 1e-9)
    return worst + HV_MARGIN * span


def hypervolume_history(ev: Evaluations, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hypervolume after each batch: (evaluations done (k,), hypervolume (k,)), of the rows
    current then (``Evaluations.current``)."""
    ends = np.flatnonzero(np.diff(np.append(ev.iteration, -1)) != 0) + 1
    return ends, np.array([hypervolume(-ev.objectives[:e][ev.current(e)[:e]], ref) for e in ends])


def reference_from(run: Run, config: RunConfig, ev: Evaluations, store: bool = True) -> np.ndarray | None:
    """The stored reference point, or the one the warm-up defines (written once known, unless
    ``store`` is False: a reader such as the explore page leaves the run directory as it is).
    ``ev`` in batch order; the warm-up is its rows of the warm-up batches, once all are there."""
    state = run.run_state()
    if "hv_reference" in state:
        ref = np.asarray(state["hv_reference"], np.float64)
        if ref.shape != (len(config.objective_names),):
            raise RunError(f"{run.path / RUN_STATE}: hv_reference has {ref.size} values for "
                           f"{len(config.objective_names)} objectives; delete it and --resume recomputes it")
        return ref
    warmup = ev.iteration < _warmup_batches(config)
    if warmup.sum() < min(config.n_init, config.training_rows):
        return None
    ref = hypervolume_reference(ev.objectives[warmup])
    if store:
        run.write_run_state({**state, "hv_reference": ref.tolist(), "hv_space": "negated objectives (minimized)"})
    return ref


def _warmup_batches(config: RunConfig) -> int:
    """How many batches the random warm-up takes (``batch_sizes`` stops it at n_init points)."""
    ends = np.cumsum(list(batch_sizes(config.training_rows, config.batch_size, config.n_init)))
    return int(np.searchsorted(ends, min(config.n_init, config.training_rows)) + 1)


def pareto_mask_of(ev: Evaluations) -> np.ndarray:
    """(n,) bool: the non-dominated rows (objectives maximized) among the current ones (a row
    that a later one pooling more worlds of its parameter set replaces is no longer one)."""
    mask = np.zeros(len(ev), bool)
    current = ev.current()
    if current.any():
        mask[current] = pareto_mask(-ev.objectives[current])
    return mask
