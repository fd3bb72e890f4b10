"""Random hypervolume scalarizations (Golovin and Zhang 2020) and their quasi-MC log-EI.

For minimized objectives u (m of them) and a reference point r, a direction lambda on the
positive part of the unit sphere defines

    s_lambda(u) = min_i (max(0, r_i - u_i) / lambda_i) ** m,

and for any finite set Y the dominated hypervolume is an average of its best scalarized value:

    HV(Y; r) = c_m * E_lambda[max_{y in Y} s_lambda(y)],  c_m = pi^(m/2) / (2^m Gamma(m/2 + 1)),

lambda uniform on the sphere's positive part (``sample_directions``). So the improvement of
s_lambda for one random lambda is an unbiased one-direction estimate of the hypervolume
improvement, and EI on it is a random scalarization with EI, as ParEGO (Knowles 2006) and
Paria et al. (2018), whose scalarizations recover the hypervolume in expectation. Its m-th
root, min_i (r_i - u_i) / lambda_i, is a Chebyshev scalarization anchored at the reference
point with weights 1 / lambda_i (rather than at the ideal point).

Here the objectives are rescaled so that the observed ideal point is 0 and the reference
point 1 in every coordinate (``to_reference_units``): the identity above holds in any
per-axis scaling (hypervolume scales by a constant), and in these units the directions spread
over the part of the front that counts for the hypervolume. Values beyond the reference point
(u > 1) are log-compressed (``compress_beyond_reference``): monotone, so dominance and every
s_lambda are unchanged where they are not 0, but a heavy tail of bad values (Branin's ~300
next to a reference of 18) no longer sets the GP's mean and scale.

``scalarize`` extends s_lambda below 0 by the (negative) anchored Chebyshev value where some
objective is beyond the reference point: equal to s_lambda where that is positive, and still
increasing towards the dominated region, so EI keeps a gradient and an incumbent exists
before anything dominates the reference point.
"""

from __future__ import annotations

import math
from functools import lru_cache

import jax
import jax.numpy as jnp
import numpy as np
from scipy.stats import qmc

from mjxskill.gp.pareto import pareto_mask
from mjxskill.gp.scalarized_posterior import centred_normal_quantiles, log_mean_softplus


def hypervolume_constant(m: int) -> float:
    """c_m = pi^(m/2) / (2^m Gamma(m/2 + 1)): the volume of the unit ball's positive orthant."""
    return math.pi ** (m / 2) / (2**m * math.gamma(m / 2 + 1))


def sample_directions(key, num: int, m: int) -> jnp.ndarray:
    """(num, m) directions uniform on the positive part of the unit sphere (|normal| normalized)."""
    z = jnp.abs(jax.random.normal(key, (num, m), jnp.float64))
    return z / jnp.linalg.norm(z, axis=-1, keepdims=True)


@lru_cache(maxsize=None)
def _sobol_points(num: int, dim: int, seed: int = 0) -> np.ndarray:
    """(num, dim) scrambled Sobol points in [0, 1)^dim (fixed seed; host side, cached)."""
    return qmc.Sobol(dim, scramble=True, seed=seed).random(num)


def _direction_dims(m: int) -> int:
    """Coordinates of the unit cube that ``_to_directions`` maps to one direction of m objectives."""
    return {2: 1, 3: 2}.get(m, m)


def _to_directions(u: jnp.ndarray, m: int) -> jnp.ndarray:
    """Points of the unit cube -> directions on the sphere's positive part, area-preserving
    where a simple map exists, so an even set of points stays an even set of directions:
    m = 2 by angle (u (..., 1)), m = 3 by Archimedes' hat-box map (height and azimuth,
    u (..., 2)); otherwise the normalized |normal quantile| of u (..., m), which keeps each
    direction uniform but not the set's evenness."""
    if m == 2:
        angle = 0.5 * jnp.pi * u[..., 0]
        return jnp.stack([jnp.cos(angle), jnp.sin(angle)], axis=-1)
    if m == 3:
        height, azimuth = u[..., 0], 0.5 * jnp.pi * u[..., 1]
        radius = jnp.sqrt(jnp.maximum(1.0 - height**2, 0.0))
        return jnp.stack([radius * jnp.cos(azimuth), radius * jnp.sin(azimuth), height], axis=-1)
    z = jnp.abs(jax.scipy.special.ndtri(jnp.clip(u, 1e-12, 1.0 - 1e-12)))
    return z / jnp.maximum(jnp.linalg.norm(z, axis=-1, keepdims=True), 1e-300)


def quasi_random_directions(key, groups: int, num: int, m: int, paired_draws: bool = False) -> jnp.ndarray:
    """(groups, num, m) directions, each group a randomized quasi-Monte Carlo set on the
    positive part of the unit sphere: one Sobol set shifted modulo 1 by a uniform vector per
    group (Cranley-Patterson rotation), mapped by ``_to_directions``.

    Every direction is still uniform on the sphere's positive part (so an average over a
    group is an unbiased estimate of the hypervolume identity's expectation), but a group
    covers it evenly: independent directions leave most of the narrow gaps of a dense front
    unsampled, and the estimate's variance, not the model, then decides where a point goes.

    paired_draws: the direction coordinates of the joint Sobol set whose other coordinates
    are ``paired_normal_draws``'s first draw per direction (False: a Sobol set of directions
    alone).
    """
    dim = _direction_dims(m)
    points = jnp.asarray(_sobol_points(num, dim + m)[:, :dim] if paired_draws else _sobol_points(num, dim))
    shift = jax.random.uniform(key, (groups, 1, dim), jnp.float64)
    return _to_directions(jnp.mod(points[None] + shift, 1.0), m)


def paired_normal_draws(num: int, per_direction: int, m: int) -> np.ndarray:
    """(num, per_direction, m) quasi-random standard normal draws, a block per direction of
    ``quasi_random_directions(..., paired_draws=True)``, centred per objective.

    Draw 0 of direction i is the normal quantile of the last m coordinates of row i of the
    joint Sobol set whose first coordinates are direction i's, so (direction, draw) pairs
    cover their joint space evenly; draw t > 0 takes them from the same set scrambled with
    seed t. Two Sobol sets scrambled alike are no pairing: with one seed a direction's
    coordinate and its draw's first coordinate correlate at 0.75 (the same scrambling
    matrix for the first dimension), which ties a direction to where its draw falls.
    """
    dim = _direction_dims(m)
    u = np.stack([_sobol_points(num, dim + m, seed)[:, dim:] for seed in range(per_direction)], axis=1)
    return centred_normal_quantiles(u)


def anchored_chebyshev(u: jnp.ndarray, direction: jnp.ndarray) -> jnp.ndarray:
    """min_i (1 - u_i) / lambda_i for u (..., m) in reference units (reference at 1): (...,).

    Larger is better; positive exactly when u dominates the reference point strictly.
    """
    return jnp.min((1.0 - u) / direction, axis=-1)


def scalarize(u: jnp.ndarray, direction: jnp.ndarray) -> jnp.ndarray:
    """Hypervolume scalarization s_lambda(u) (..., m) -> (...), extended below 0 (see the
    module docstring): t^m for t = anchored_chebyshev(u) >= 0, t for t < 0. Larger is better."""
    t = anchored_chebyshev(u, direction)
    m = u.shape[-1]
    return jnp.where(t > 0.0, jnp.maximum(t, 0.0) ** m, t)


def reference_scaling(y: jnp.ndarray, mask: jnp.ndarray, ref: jnp.ndarray):
    """(ideal (m,), span (m,)) of :func:`to_reference_units`: u = (y - ideal) / span."""
    ideal = jnp.min(jnp.where(mask[:, None], y, jnp.inf), axis=0)
    worst = jnp.max(jnp.where(mask[:, None], y, -jnp.inf), axis=0)
    span = ref - ideal
    fallback = jnp.where(worst > ideal, worst - ideal, 1.0)
    span = jnp.where(span > 1e-12 * fallback, span, fallback)
    return ideal, span


def to_reference_units(y: jnp.ndarray, mask: jnp.ndarray, ref: jnp.ndarray) -> jnp.ndarray:
    """(n, m) objectives -> (y - ideal) / (ref - ideal), ideal the best masked-in value.

    ref (m,) in the units of y. Where ref is not above the ideal (a reference point that
    nothing reaches yet), the span falls back to the observed range so the scale stays finite.
    """
    ideal, span = reference_scaling(y, mask, ref)
    return (y - ideal) / span


def non_dominated(u: jnp.ndarray, mask: jnp.ndarray) -> jnp.ndarray:
    """(n,) bool, jittable: the masked-in rows of u (n, m) (minimized) that no other masked-in
    row dominates (equal rows do not dominate each other)."""
    rows = mask[:, None] & mask[None, :]
    dominates = jnp.all(u[:, None] <= u[None], axis=-1) & jnp.any(u[:, None] < u[None], axis=-1)  # [j, i]: j dominates i
    return mask & ~jnp.any(dominates & rows, axis=0)


def front_reference(u: jnp.ndarray, mask: jnp.ndarray, margin: float) -> jnp.ndarray:
    """(m,) the observed front's own reference point in reference units (jittable): its nadir
    plus ``margin`` times its extent, by ``reference_point``'s rule (an objective where the
    front has no extent takes the margin of the observed range, or of 1), at most the run's
    reference (1). Directions about it spread over the front's trade-off, where about a
    distant reference most of them favour one objective alone and end at an extreme that
    nothing can improve."""
    on_front = non_dominated(u, mask)
    nadir = jnp.max(jnp.where(on_front[:, None], u, -jnp.inf), axis=0)
    extent = nadir - jnp.min(jnp.where(on_front[:, None], u, jnp.inf), axis=0)
    observed = jnp.max(jnp.where(mask[:, None], u, -jnp.inf), axis=0) - jnp.min(jnp.where(mask[:, None], u, jnp.inf), axis=0)
    extent = jnp.where(extent > 0, extent, jnp.where(observed > 0, observed, 1.0))
    return jnp.clip(nadir + margin * extent, 1e-6, 1.0)


def compress_beyond_reference(u: jnp.ndarray) -> jnp.ndarray:
    """u for u <= 1, 1 + log(u) above: continuous with its first derivative, monotone."""
    return jnp.where(u > 1.0, 1.0 + jnp.log(jnp.maximum(u, 1.0)), u)


def compress_beyond_reference_slope(u: jnp.ndarray) -> jnp.ndarray:
    """The derivative of :func:`compress_beyond_reference` at u: 1 for u <= 1, 1 / u above."""
    return jnp.where(u > 1.0, 1.0 / jnp.maximum(u, 1.0), 1.0)


def log_ei_hv_draws(mean: jnp.ndarray, variance: jnp.ndarray, direction: jnp.ndarray, draws: jnp.ndarray, best,
                    tau: float = 1e-3, shift: jnp.ndarray | None = None) -> jnp.ndarray:
    """Quasi-MC log E[max(scalarize(f) - best, 0)] for independent f_i ~ N(mean_i, variance_i).

    Args:
      mean, variance: (b, m) per-objective posteriors in reference units.
      direction: (m,) the element's lambda, or (k, m) several, whose improvements are averaged
        (with ``best`` (k,)): c_m times that average is a k-direction Monte Carlo estimate of
        the expected hypervolume improvement.
      draws: (s, m) standard normal draws shared by the directions, or (k, s, m) each
        direction its own.
      best: the incumbent, max of ``scalarize`` over the observations (per direction), or
        (k, s) one per direction and shared draw (the front of that draw's pending values).
      tau: softplus width of the max (as in ``log_ei_draws``), keeping a gradient where no
        draw improves.
      shift: (b, s, m) the mean's shift in each shared draw (the candidate conditioned on that
        draw's pending values), or None.
    Returns:
      (b,) log-EI.
    """
    lam = jnp.atleast_2d(direction)  # (k, m)
    k, m = lam.shape
    if shift is not None:  # static
        return _log_ei_hv_shifted(mean, variance, lam, draws, best, tau, shift)
    if draws.ndim == 2:  # (s, m) shared: every direction pairs with every draw
        draws = jnp.broadcast_to(draws[None], (k,) + draws.shape)
    s = draws.shape[1]
    # The k x s (direction, draw) pairs on one flat axis, each pair's (1 - f_i) / lambda_i
    # written as (1 - mean_i) / lambda_i - sd_i z_i / lambda_i from two (pairs,) vectors per
    # objective, and the min over the m objectives unrolled: every array then has the pairs
    # on its minor axis. The direct (b, k, s, m) form, with m = 2 or 3 innermost, runs several
    # times slower on a CPU (benchmarks/RESULTS.md, "A given reference point: 2048
    # directions, a posterior draw each", "A faster estimate").
    inv = jnp.broadcast_to((1.0 / lam)[:, None], (k, s, m)).reshape(k * s, m)
    slope = draws.reshape(k * s, m) * inv  # z_i / lambda_i
    best = _pair_incumbents(best, k, s).reshape(k * s)
    # Materialized before the (b, k s) loop: fused into it, their broadcasts would cost index
    # arithmetic per element of it.
    inv, slope, best = jax.lax.optimization_barrier((inv, slope, best))
    sd = jnp.sqrt(jnp.maximum(variance, 0.0))
    t = None
    for i in range(m):  # static
        t_i = (1.0 - mean[:, i, None]) * inv[None, :, i] - sd[:, i, None] * slope[None, :, i]  # (b, k s)
        t = t_i if t is None else jnp.minimum(t, t_i)
    assert t is not None  # m >= 1 objectives
    return _log_ei_of_chebyshev(t, best, m, tau, axis=-1)


def _log_ei_hv_shifted(mean, variance, lam, draws, best, tau: float, shift):
    """``log_ei_hv_draws`` with a mean shifted per shared draw (s, m): the pairs as (k, s) axes,
    the draws minor, so that a candidate's shifted centres (b, 1, s) broadcast over the
    directions instead of being tiled into a (b, k s) array per objective (the draws' ask 6 %
    cheaper, benchmarks/NOTES.md section 29)."""
    k, m = lam.shape
    if draws.ndim != 2:  # static
        raise ValueError(f"log_ei_hv_draws: a shift needs draws (s, m) shared by the directions, got {draws.shape}")
    s = draws.shape[0]
    inv = 1.0 / lam  # (k, m)
    slope = draws[None] * inv[:, None]  # (k, s, m): z_i / lambda_i
    best = _pair_incumbents(best, k, s)
    inv, slope, best = jax.lax.optimization_barrier((inv, slope, best))
    sd = jnp.sqrt(jnp.maximum(variance, 0.0))
    t = None
    for i in range(m):  # static
        centre = (1.0 - mean[:, i, None] - shift[:, :, i])[:, None, :]  # (b, 1, s)
        t_i = centre * inv[None, :, i, None] - sd[:, i, None, None] * slope[None, :, :, i]  # (b, k, s)
        t = t_i if t is None else jnp.minimum(t, t_i)
    assert t is not None  # m >= 1 objectives
    return _log_ei_of_chebyshev(t, best, m, tau, axis=(-2, -1))


def _pair_incumbents(best, k: int, s: int) -> jnp.ndarray:
    """(k, s): the incumbent of each (direction, draw) pair, from ``best`` given once, per
    direction (k,) or per pair (k, s)."""
    return jnp.broadcast_to(best if jnp.ndim(best) == 2 else jnp.broadcast_to(best, (k,))[:, None], (k, s))


def _log_ei_of_chebyshev(t, best, m: int, tau: float, axis):
    """The log-EI over the (direction, draw) pairs on ``axis`` of the anchored Chebyshev values
    t, against the incumbent ``best`` (broadcast to t's pair axes)."""
    # scalarize's extension below 0 (t^m above, t below).
    scalarized = jnp.where(t > 0.0, jnp.maximum(t, 0.0) ** m, t)
    return log_mean_softplus((scalarized - best) / tau, axis=axis) + jnp.log(tau)


def reference_point(y: np.ndarray, margin: float = 0.1) -> np.ndarray:
    """(m,) reference point from the observed front (host side, minimization): its nadir plus
    ``margin`` times its extent per objective, as BoTorch's ``infer_reference_point``.

    y: (n, m) objective values; non-finite rows are ignored (all NaN if no row is finite).
    Where the front has no extent in an objective (one point), the margin is taken of the
    observed range, or of 1.
    """
    y = np.asarray(y, np.float64)
    finite = y[np.all(np.isfinite(y), axis=1)]
    if len(finite) == 0:
        return np.full(y.shape[1], np.nan)
    front = finite[pareto_mask(finite)]
    nadir, ideal = front.max(axis=0), front.min(axis=0)
    extent = nadir - ideal
    observed = finite.max(axis=0) - finite.min(axis=0)
    extent = np.where(extent > 0, extent, np.where(observed > 0, observed, 1.0))
    return nadir + margin * extent


def warmup_reference(y: np.ndarray, margin: float = 0.1) -> np.ndarray:
    """(m,) reference point from warm-up rows y (n, m) (host side, minimization): the worst
    finite value plus ``margin`` times the finite range per objective (1e-9 where the range
    is 0), the rule ``mjxskill.train`` reports its hypervolume against. NaN for an objective
    without any finite warm-up value."""
    y = np.asarray(y, np.float64)
    finite = np.isfinite(y)
    worst = np.max(np.where(finite, y, -np.inf), axis=0)
    best = np.min(np.where(finite, y, np.inf), axis=0)
    ref = worst + margin * np.where(worst > best, worst - best, 1e-9)
    return np.where(np.any(finite, axis=0), ref, np.nan)
