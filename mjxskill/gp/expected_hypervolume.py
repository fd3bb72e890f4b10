"""The expected hypervolume improvement in closed form, for two or three objectives.

For a new point f with independent Gaussian objectives f_i ~ N(mean_i, variance_i)
(minimized, in units where the reference point is 1 in every objective) and the points P
already found, the hypervolume improvement is the volume of the part of the box [f, 1] that
no point of P dominates. Cut the region below the reference point into a grid over the
first m - 1 objectives, at the points' own coordinates: inside one cell (a column for three
objectives, an interval for two) a point u is dominated exactly when its last objective is
at least h, the least last objective of the points that dominate the cell's lower corner
(1 where none does). The improvement is then a sum over cells of products of one factor
per objective,

    prod_{i < m-1} |[max(f_i, lo_i), hi_i]|  x  |[f_{m-1}, h]|,

and since the objectives are independent its expectation is the same sum of products of
univariate expectations (Emmerich et al. 2006; Yang et al. 2019 for the grid): with
EI(c) = E[max(c - f_i, 0)], the closed-form expected improvement,
E|[max(f_i, lo), hi]| = EI(hi) - EI(lo) and E|[f_{m-1}, h]| = EI(h). Everything is in log
space (``acquisition.log_h``): far from the front the expectation underflows long before
its logarithm loses its gradient.

The grid has (n + 1)^(m - 1) cells for n points, which is why this stops at three
objectives; cells of zero width (repeated coordinates, and the points that do not dominate
the reference point, which take the reference point's place) are masked out. Unlike the
hypervolume scalarization's Monte Carlo estimate over directions
(``hypervolume_scalarization.log_ei_hv_draws``) it has no sampling error, which matters
late in a run, when the improvement left lies in narrow gaps of the front that few
directions cross (benchmarks/RESULTS.md, "Three objectives: the expected hypervolume
improvement in closed form").
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from mjxskill.gp.acquisition import _log1mexp, log_ei
from mjxskill.gp.hypervolume_scalarization import non_dominated

MAX_OBJECTIVES = 3


def _log_cell_widths(edges: jnp.ndarray, mean: jnp.ndarray, variance: jnp.ndarray) -> jnp.ndarray:
    """log E|[max(f, lo_c), hi_c]| for the cells c of one objective, (b, k + 1).

    edges: (k + 1,) the sorted finite edges e_0 <= ... <= e_k (the last is the reference,
    1); cell 0 is (-inf, e_0], cell c > 0 is [e_{c-1}, e_c]. mean, variance: (b,).
    """
    log_ei_edges = log_ei(mean[:, None], variance[:, None], edges[None, :])  # (b, k + 1), nondecreasing
    inner = log_ei_edges[:, 1:] + _log1mexp(log_ei_edges[:, :-1] - log_ei_edges[:, 1:])
    inner = jnp.where(edges[None, 1:] > edges[None, :-1], inner, -jnp.inf)
    return jnp.concatenate([log_ei_edges[:, :1], inner], axis=1)


class Grid(NamedTuple):
    """The cells of the region below the reference point that ``points`` leave undominated
    (``grid``): per grid objective (the first m - 1) the sorted edges (n + 1,), and each
    cell's h as an index into ``levels`` (n + 1,), the points' last objective and then 1."""

    edges: tuple
    level: jnp.ndarray
    levels: jnp.ndarray


def grid(points: jnp.ndarray, max_points: int | None = None) -> Grid:
    """The grid of ``points`` (n, m), m = 2 or 3, in units where the reference point is 1; a
    point that is not below the reference point in every objective dominates nothing of the
    box and is ignored (set a padding row to 1). It depends on the points alone: build it
    once per set of points, outside the loop over candidates.

    max_points (static): the grid is built on at most this many rows, the non-dominated
    points first (a dominated point changes no cell's h, only splits cells), which bounds
    the (n + 1)^(m - 1) cells a candidate costs. Where more points than that are
    non-dominated, the later rows are left out and the improvement near them overestimated.
    """
    m = points.shape[-1]
    if m not in (2, MAX_OBJECTIVES):  # static
        raise ValueError(f"the closed-form expected hypervolume improvement takes 2 or 3 objectives, got {m}")
    inside = jnp.all(points < 1.0, axis=-1)
    p = jnp.where(inside[:, None], points, 1.0)
    if max_points is not None and max_points < p.shape[0]:  # static
        front = non_dominated(p, inside)
        kept = jnp.argsort(~front, stable=True)[:max_points]
        p = jnp.where(front[kept][:, None], p[kept], 1.0)
    n = p.shape[0]
    one = jnp.ones((1,), p.dtype)
    edges = tuple(jnp.concatenate([jnp.sort(p[:, i]), one]) for i in range(m - 1))
    # Each cell's lower corner: -inf for cell 0, else the edge below it.
    lower = [jnp.concatenate([-jnp.inf * one, e[:-1]]) for e in edges]
    if m == 2:  # static
        dominates = p[None, :, 0] <= lower[0][:, None]  # (n + 1, n)
    else:
        dominates = (p[None, None, :, 0] <= lower[0][:, None, None]) & (p[None, None, :, 1] <= lower[1][None, :, None])
    last = jnp.where(dominates, p[:, m - 1], jnp.inf)
    level = jnp.where(jnp.any(dominates, axis=-1), jnp.argmin(last, axis=-1), n)  # (n + 1,) or (n + 1, n + 1)
    return Grid(edges, level, jnp.concatenate([p[:, m - 1], one]))


def log_expected_improvement(mean: jnp.ndarray, variance: jnp.ndarray, cells: Grid) -> jnp.ndarray:
    """log E[hypervolume improvement of f over the points of ``cells``], f_i ~ N(mean_i, variance_i)
    independent.

    Args:
      mean, variance: (b, m) the candidates' posteriors, in the units of the grid's points
        (the reference point at 1, minimized; values below 0 are fine).
      cells: ``grid(points)``.
    Returns:
      (b,) log of the expected improvement of the box [f, 1]'s volume.
    """
    m = mean.shape[-1]
    widths = [_log_cell_widths(cells.edges[i], mean[:, i], variance[:, i]) for i in range(m - 1)]  # each (b, n + 1)
    log_ei_levels = log_ei(mean[:, m - 1, None], variance[:, m - 1, None], cells.levels[None, :])  # (b, n + 1)
    # log_ei_levels[:, level] as a product with the one-hot matrix of the levels: exact (one
    # term of each sum is not 0 x a finite value), and many times faster on a CPU than XLA's
    # gather, which loops over the (b, cells) elements one by one.
    one_hot = (cells.level.reshape(-1)[None, :] == jnp.arange(cells.levels.shape[0])[:, None]).astype(mean.dtype)
    at_cells = log_ei_levels @ one_hot  # (b, cells)
    if m == 2:  # static
        terms = widths[0] + at_cells
    else:
        terms = (widths[0][:, :, None] + widths[1][:, None, :]).reshape(at_cells.shape) + at_cells
    return jax.nn.logsumexp(terms, axis=-1)
