"""The q batch elements' random scalarizations: what the proposal's two models need of them.

Element j scalarizes the objectives its own random way (``settings.scalarization``): random
hypervolume scalarizations about a reference point (most elements averaging
``n_directions`` quasi-random directions, a Monte Carlo estimate of the expected hypervolume
improvement, or with ``hypervolume_improvement="exact"`` that expectation in closed form,
``expected_hypervolume.py``; the last ``single_direction_share`` following one direction
each), or augmented Chebyshev on flat Dirichlet weights (ParEGO). ``element_scalarizations``
returns their targets for the scalarized model, their incumbents and log-EI for the
per-objective model (``proposal.py``), and the factors that carry a noise variance of the
normalized objectives into the space the per-objective GPs are fitted in.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp

from mjxskill.gp import expected_hypervolume as ehv
from mjxskill.gp import hypervolume_scalarization as hvs
from mjxskill.gp.acquisition import chebyshev, log_ei, sample_simplex
from mjxskill.gp.scalarized_posterior import chebyshev_moments, log_ei_draws, normal_draws
from mjxskill.gp.settings import AcquisitionSettings


class Scalarization(NamedTuple):
    """What the two models need of the q elements' scalarizations (see ``_scalarization``).

    space: (n, m) objectives the per-objective GPs are fitted to (minimized).
    targets: (q, n) each element's scalarized observations, to be minimized (scalarized model).
    directions: (q, m) Chebyshev weights, or (q, k, m) each element's hypervolume directions.
    scale: (q, m) each element's reference point in ``space`` units (hypervolume: 1, the run's
      reference, or the front's own; an element scalarizes space / scale). Chebyshev: ones.
    incumbents: values (n, m) in ``space`` units, mask (n,) -> each element's incumbent (its
      best scalarized value; (q,) or (q, k) for k directions per element; with the exact
      hypervolume improvement that and the points themselves, (q, n, m) in element units),
      from the observed values or from the model's posterior means at the observed points.
    log_ei: (j, incumbent_j, pending (q, m), pending_mask (q,)) -> a function of mean (b, m),
      variance (b, m) -> (b,): the log-EI of element j's scalarization of independent
      Gaussian objectives in ``space`` units (per-objective model); with
      ``settings.pending == "values"`` the incumbent also counts the pending points at their
      believed (posterior mean) values. What depends on the incumbent and the pending points
      alone is computed once, outside the loop over candidates.
    variance_factor: (n, m) the factor that turns a noise variance of row i's normalized
      objective k into that of its ``space`` value (delta method: the squared derivative of
      the map from y_norm to ``space`` at that row, 1 / span^2 of the reference units, times
      1 / u^2 where the value is log-compressed beyond the reference point; Chebyshev: ones).
    new_variance_factor: (m,) the same for a new observation, whose value is not known: the
      factor of a value within the reference point (an upper bound: the compression only
      shrinks it).
    """

    space: jnp.ndarray
    targets: jnp.ndarray
    incumbents: Callable[[jnp.ndarray, jnp.ndarray], Any]  # -> a pytree of incumbents
    log_ei: Callable[..., Callable[[jnp.ndarray, jnp.ndarray], jnp.ndarray]]
    directions: jnp.ndarray
    scale: jnp.ndarray
    variance_factor: jnp.ndarray
    new_variance_factor: jnp.ndarray


def element_scalarizations(y_norm, mask, ref, key, q: int, settings: AcquisitionSettings) -> Scalarization:
    """The q elements' random scalarizations: augmented Chebyshev on Dirichlet weights, or
    hypervolume scalarizations on uniform directions (``hypervolume_scalarization.py``).

    y_norm: (n, m) normalized objectives (minimized); mask: (n,) bool real rows; ref: (m,)
    reference point in y_norm's units; key: PRNG key of the weights or directions.
    """
    m = y_norm.shape[1]
    k = settings.n_directions
    paired = settings.draw_pairing == "per_direction"
    if settings.scalarization == "chebyshev":  # static
        # Per-direction pairing: n_directions x n_draws distinct draws, all for its one weight.
        draws = jnp.asarray(normal_draws(settings.n_draws * (k if paired else 1), m))
        weights = sample_simplex(key, q, m)
        targets = jax.vmap(lambda w: chebyshev(y_norm, w, settings.alpha))(weights)

        def incumbents(values, rows):  # (q,): minimized
            scal = jax.vmap(lambda w: chebyshev(values, w, settings.alpha))(weights)
            return jnp.min(jnp.where(rows[None], scal, jnp.inf), axis=1)

        def log_ei_of(j, b, pending, pending_mask):
            if settings.pending == "values":  # static
                b = jnp.minimum(b, jnp.min(jnp.where(pending_mask, chebyshev(pending, weights[j], settings.alpha), jnp.inf)))
            if settings.ei == "draws":  # static
                return lambda mean, var: log_ei_draws(mean, var, weights[j], settings.alpha, draws, b, settings.tau)
            return lambda mean, var: log_ei(*chebyshev_moments(mean, var, weights[j], settings.alpha, draws), b)

        return Scalarization(y_norm, targets, incumbents, log_ei_of, weights, jnp.ones((q, m), y_norm.dtype),
                             jnp.ones_like(y_norm), jnp.ones((m,), y_norm.dtype))
    # (k, n_draws, m), a block per direction, or (n_draws, m) shared by all (static).
    draws = jnp.asarray(hvs.paired_normal_draws(k, settings.n_draws, m) if paired else normal_draws(settings.n_draws, m))
    _, span = hvs.reference_scaling(y_norm, mask, ref)
    u = hvs.to_reference_units(y_norm, mask, ref)
    new_factor = 1.0 / span**2
    factor = jnp.broadcast_to(new_factor, u.shape)
    if settings.beyond_reference == "log":  # static
        factor = factor * hvs.compress_beyond_reference_slope(u) ** 2
        u = hvs.compress_beyond_reference(u)
    if settings.directions == "quasi_random":  # static
        directions = hvs.quasi_random_directions(key, q, k, m, paired_draws=paired)
    else:
        directions = hvs.sample_directions(key, q * k, m).reshape(q, k, m)
    n_single = round(settings.single_direction_share * q)
    # Each element's reference point in reference units (1: the run's); u / scale is what it scalarizes.
    scale = jnp.ones((q, m), u.dtype)
    if n_single and k > 1:  # static: the last elements follow one random direction each
        single = jnp.arange(q) >= q - n_single
        directions = jnp.where(single[:, None, None], directions[:, :1], directions)
        if settings.single_direction_reference == "front":  # static
            local = hvs.front_reference(u, mask, settings.ref_margin)
            scale = jnp.where(single[:, None], local[None], scale)
    # The scalarized model's GP sees the m-th root (the anchored Chebyshev value, smoother)
    # of the element's first direction.
    targets = -jax.vmap(lambda lam, r: hvs.anchored_chebyshev(u / r, lam))(directions[:, 0], scale)

    def best_scalarized(values, rows):  # (q, k): maximized
        scal = jax.vmap(lambda lams, r: jax.vmap(lambda lam: hvs.scalarize(values / r, lam))(lams))(directions, scale)
        return jnp.max(jnp.where(rows, scal, -jnp.inf), axis=-1)

    def log_ei_directions(j, b, pending, pending_mask):
        r = scale[j]
        if settings.pending == "values":  # static
            believed = jax.vmap(lambda lam: hvs.scalarize(pending / r, lam))(directions[j])  # (k, q)
            b = jnp.maximum(b, jnp.max(jnp.where(pending_mask, believed, -jnp.inf), axis=-1))
        elif settings.pending == "draws":  # static: pending (s, q, m), a joint draw of them per shared draw
            drawn = jax.vmap(lambda lam: jax.vmap(lambda v: hvs.scalarize(v / r, lam))(pending))(directions[j])  # (k, s, q)
            b = jnp.maximum(b[:, None], jnp.max(jnp.where(pending_mask, drawn, -jnp.inf), axis=-1))  # (k, s)
        return lambda mean, var, shift=None: hvs.log_ei_hv_draws(mean / r, var / r**2, directions[j], draws, b,
                                                                 settings.tau, None if shift is None else shift / r)

    directed = Scalarization(u, targets, best_scalarized, log_ei_directions, directions, scale, factor, new_factor)
    if settings.hypervolume_improvement == "directions" or m > ehv.MAX_OBJECTIVES:  # static
        return directed
    return _with_exact_improvement(directed, q, n_single if k > 1 else 0, settings)


def _with_exact_improvement(scal: Scalarization, q: int, n_single: int, settings: AcquisitionSettings) -> Scalarization:
    """``scal`` with the closed-form expected hypervolume improvement (element units: the
    run's reference at 1) over the observed points, or their posterior means, and with
    pending="values" the pending points at their believed values too; the last ``n_single``
    elements, which follow a single direction, keep it."""
    m = scal.space.shape[1]
    max_points = settings.exact_max_points if m == ehv.MAX_OBJECTIVES else None  # static

    def incumbents(values, rows):  # ((q, k), (q, n, m))
        points = jnp.where(rows[None, :, None], values[None] / scal.scale[:, None, :], 1.0)
        return scal.incumbents(values, rows), points

    def log_ehvi(j, b, pending, pending_mask):
        b_directions, points = b
        if settings.pending == "values":  # static
            points = jnp.concatenate([points, jnp.where(pending_mask[:, None], pending, 1.0)])
        # An element without a single direction scalarizes about the run's reference (scale 1),
        # so mean and var need no rescaling.
        cells = ehv.grid(points, max_points)
        exact = lambda mean, var: ehv.log_expected_improvement(mean, var, cells)  # noqa: E731
        if not n_single:  # static: no element follows a single direction
            return exact
        directed = scal.log_ei(j, b_directions, pending, pending_mask)
        return lambda mean, var: jax.lax.cond(j >= q - n_single, directed, exact, mean, var)

    return scal._replace(incumbents=incumbents, log_ei=log_ehvi)
