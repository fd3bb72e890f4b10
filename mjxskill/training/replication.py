"""The robust protocol's replication (``mjxskill.runs.training_protocol``): which parameter sets a
batch rolls out again, how a row pools a set's worlds, and what the optimizer fits.

A row of a pooled run holds the means over every world its parameter set was rolled out in so
far (``worlds``), the per-objective world-to-world standard deviation over them (``spread``),
and the success bound over them (the last objective). Rolling a set out again appends a row
that pools its earlier row's worlds with the new ones and names that row (``replaces``); the
earlier row stays in the file (nothing written is rewritten) but is no longer current.

What the optimizer fits (``model_view``): per current row, the scenario's objectives and the
success *rate* (the bound is what the front and the pick rank by, the rate is what a model of
the parameters can be smooth in), each with its noise variance, its spread's square over its
worlds. A spread from a few worlds is itself noisy (7 successes of 7 have none), so it is
shrunk toward the column's mean spread with ``SPREAD_PRIOR_WORLDS`` worlds' weight (the
posterior mean of a scaled-inverse-chi-square variance): a lucky set's mean keeps a noise that
its neighbours can overrule.

Which sets are rolled out again (``choose``): the current ones the success model (a GP of the
success rate with those noises, ``mjxskill.training.success_gp``) believes most successful, each up to
``MAX_WORLDS_FACTOR`` x ``worlds`` worlds. The model pools what the neighbours of a set did, so
a set that passed its 7 worlds in a region where most sets fail is not believed; rolling the
believed-best sets out again tightens the estimates where the pick will be made.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mjxskill.errors import RunError
from mjxskill.runs.evaluations_csv import FORCE_COLUMNS, Evaluations
from mjxskill.runs.training_protocol import MAX_WORLDS_FACTOR, pooled_moments, success_lower_bound

SPREAD_PRIOR_WORLDS = 7.0  # the weight, in worlds, of a column's mean spread in each row's noise


class PooledResult(NamedTuple):
    """What rolling ``n`` parameter sets out in ``worlds`` worlds each gives, per set: the
    scenario's objectives (n, O) and their world-to-world spread (n, O) (sample sd, ddof 1),
    the success rate (n,) and the force columns (each (n,), means over the worlds)."""

    objectives: np.ndarray
    spread: np.ndarray
    success_rate: np.ndarray
    forces: tuple
    worlds: int


def check_pointers(ev: Evaluations, where: str) -> None:
    """RunError unless every ``replaces`` of the pooled rows ``ev`` (in batch order) names an
    earlier current row of the same parameter set, each row replaced at most once."""
    if not ev.pooled:
        return
    seen = set()
    # a pooled run's rows have worlds, replaces and spread
    for i, r in enumerate(ev.replaces):  # type: ignore[arg-type]
        r = int(r)
        if r < 0:
            continue
        # a pooled run's rows have worlds, replaces and spread
        if r >= i or r in seen or not np.array_equal(ev.params[r], ev.params[i]) or ev.worlds[r] >= ev.worlds[i]:  # type: ignore[index]
            raise RunError(f"{where}: row {i} (batch {int(ev.iteration[i])}) says it replaces row {r}, which is not an "
                           f"earlier row of its parameter set with fewer worlds; the file was edited or damaged")
        seen.add(r)


def new_rows(batch: int, params: np.ndarray, result: PooledResult) -> Evaluations:
    """The rows of parameter sets rolled out for the first time."""
    n = len(params)
    rate = np.asarray(result.success_rate, np.float64)
    bound = success_lower_bound(rate * result.worlds, np.full(n, float(result.worlds)))
    spread = np.concatenate([result.spread, _success_spread(rate, np.full(n, result.worlds))[:, None]], axis=1)
    return Evaluations(np.full(n, batch), np.asarray(params, np.float64),
                       np.concatenate([result.objectives, bound[:, None]], axis=1), rate,
                       *(np.asarray(f, np.float64) for f in result.forces),
                       # forces: the three force columns
                       worlds=np.full(n, result.worlds), replaces=np.full(n, -1), spread=spread)  # type: ignore[misc]


def pooled_rows(batch: int, earlier: Evaluations, rows: np.ndarray, result: PooledResult) -> Evaluations:
    """The rows that pool ``earlier``'s current rows ``rows`` (indices in batch order) with the
    new worlds of ``result`` (the same parameter sets, in that order)."""
    old = earlier.take(rows)
    k = old.objectives.shape[1] - 1  # the scenario's objectives; the last is the success bound
    # a pooled run's rows have worlds, replaces and spread
    n, means, spreads = pooled_moments(old.worlds[:, None], old.objectives[:, :k], old.spread[:, :k],  # type: ignore[index]
                                       result.worlds, result.objectives, result.spread)
    worlds = n[:, 0]
    rate = (old.success_rate * old.worlds + result.success_rate * result.worlds) / worlds
    forces = [(getattr(old, c) * old.worlds + np.asarray(f, np.float64) * result.worlds) / worlds
              for c, f in zip(FORCE_COLUMNS, result.forces)]
    bound = success_lower_bound(rate * worlds, worlds)
    spread = np.concatenate([spreads, _success_spread(rate, worlds)[:, None]], axis=1)
    return Evaluations(np.full(len(rows), batch), old.params, np.concatenate([means, bound[:, None]], axis=1), rate,
                       # forces: the three force columns
                       *forces, worlds=worlds.astype(int), replaces=np.asarray(rows, int), spread=spread)  # type: ignore[misc]


def _success_spread(rate: np.ndarray, worlds: np.ndarray) -> np.ndarray:
    """The sample sd (ddof 1) of per-world successes (0 or 1) at ``rate`` over ``worlds``."""
    worlds = np.asarray(worlds, np.float64)
    return np.where(worlds > 1, np.sqrt(np.maximum(rate * (1 - rate), 0.0) * worlds / np.maximum(worlds - 1, 1)),
                    np.nan)


def model_view(ev: Evaluations) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(params (c, P), values (c, O) maximized, noise variances (c, O)) of the current rows of
    pooled ``ev``: the scenario's objectives and the success rate (not its bound: module
    docstring), each value's noise its shrunk spread squared over its worlds."""
    current = ev.take(ev.current())
    values = np.concatenate([current.objectives[:, :-1], current.success_rate[:, None]], axis=1)
    # a pooled run's rows have worlds, replaces and spread
    return current.params, values, noise_variances(current.spread, current.worlds, values)  # type: ignore[arg-type]


def noise_variances(spread: np.ndarray, worlds: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(c, O) each row's noise variance of its mean: its spread squared, shrunk toward the
    column's mean squared spread with SPREAD_PRIOR_WORLDS worlds' weight, over its worlds; 0
    where the value is not finite (the optimizer replaces it by the worst value)."""
    n = np.asarray(worlds, np.float64)[:, None]
    var = np.asarray(spread, np.float64) ** 2
    usable = np.isfinite(var) & (n > 1) & np.isfinite(values)
    typical = np.array([var[usable[:, j], j].mean() if usable[:, j].any() else 0.0 for j in range(var.shape[1])])
    dof = np.where(usable, n - 1, 0.0)
    shrunk = (np.where(usable, var, 0.0) * dof + typical * SPREAD_PRIOR_WORLDS) / (dof + SPREAD_PRIOR_WORLDS)
    return np.where(np.isfinite(values), shrunk / n, 0.0)


def choose(ev: Evaluations, count: int, worlds: int, bounds, key) -> np.ndarray:
    """The rows (indices into ``ev``, batch order) of the ``count`` current parameter sets to roll
    out again: the ones the success model believes most successful, among those with fewer than
    MAX_WORLDS_FACTOR x ``worlds`` worlds and finite objectives; ties: the higher first
    objective, then the earlier row. Fewer (maybe none) when fewer are eligible."""
    current = np.flatnonzero(ev.current())
    rows = ev.take(current)
    # a pooled run's rows have worlds, replaces and spread
    eligible = (rows.worlds < MAX_WORLDS_FACTOR * worlds) & np.all(np.isfinite(rows.objectives), axis=1)  # type: ignore[operator]
    if count < 1 or not eligible.any():
        return np.zeros(0, int)
    # lazy: jax and gp's GP (~2 s); train's --help and bad-input errors import this module
    from mjxskill.training.success_gp import success_model

    _, values, noise = model_view(ev)
    believed = success_model(rows.params, values[:, -1], noise[:, -1], bounds, key)
    order = np.lexsort((np.arange(len(rows)), -rows.objectives[:, 0], -believed))
    return current[[i for i in order if eligible[i]][:count]]


__all__ = ["PooledResult", "SPREAD_PRIOR_WORLDS", "check_pointers", "choose", "model_view", "new_rows", "noise_variances",
           "pooled_rows"]
