"""One model-based batch: fit GPs, then pick q points by sequential greedy log-EI.

Element j of the batch scalarizes the objectives its own random way (``settings.scalarization``;
``element_scalarizations.py``):

* "hypervolume": random hypervolume scalarizations about a reference point (Golovin and
  Zhang 2020; ``hypervolume_scalarization.py``). Most elements average ``n_directions``
  quasi-random directions, a Monte Carlo estimate of the expected hypervolume improvement;
  the last ``single_direction_share`` of the batch follow one direction each (a single
  random scalarization), about the observed front's own reference point when
  ``single_direction_reference="front"``. With ``hypervolume_improvement="exact"`` (two or
  three objectives, per-objective model) the averaging elements take the expected
  hypervolume improvement in closed form instead (``expected_hypervolume.py``);
* "chebyshev": augmented Chebyshev on a flat Dirichlet weight w_j (ParEGO).

Two models of the scalarization, combined by ``settings.model``:

* "scalarized": a GP fitted to the element's scalarized values (details below);
* "per_objective": one GP per objective (standardized), shared by all elements; the
  acquisition is the log-EI of the scalarization of quasi-random posterior draws
  (``scalarized_posterior.py``, ``hypervolume_scalarization.log_ei_hv_draws``). Its incumbent
  is the best scalarized observed value or, with ``incumbent="posterior_mean"``, the best
  scalarized posterior mean at the observed points, and with ``variance="deflated"`` its
  variance excludes the fitted noise, so that re-evaluating an observed point offers no
  spurious improvement;
* "hybrid": the first ceil(q/2) elements scalarized, the rest per-objective, all in one
  greedy sequence.

Known observation noise (``obs_noise``, ``new_noise``; per-objective model only): a row that
is the mean of several noisy evaluations has its own noise variance per objective. It is
carried into the space each per-objective GP is fitted in (``Scalarization.variance_factor``,
then standardization) and added to that GP's covariance diagonal beside its fitted noise
(``gp.py``); the Kriging believer's pending points get the noise of one new observation.

The defaults (``settings.AcquisitionSettings``, and ``settings.GIVEN_REFERENCE_DEFAULTS``
when the reference point is given) and the measurements that chose them:
benchmarks/RESULTS.md, "Multi-objective BO quality".

Scalarized model: the targets are element j's scalarized values, standardized (the augmented
Chebyshev of the normalized objectives, or for hypervolume scalarizations the anchored
Chebyshev value of its first direction, the smoother m-th root). While the padded
training set is small (at most ``per_element_fit_max_rows`` rows) each element gets its own
GP hyperparameter fit (RESULTS.md, 'Previous defaults (model = "scalarized")'). Above that
size one fit on the first scalarization is shared by the batch, because q fits of O(n^3)
each would dominate the proposal time. For either model, when the padded training set has
more than ``fit_max_rows`` rows the hyperparameters are fitted on a random subset of at most
that many real rows (subset-of-data estimation). The posterior always conditions on every
row.

Kriging believer: element j conditions on the points already chosen for elements < j with
its own posterior mean as their value. That leaves its mean unchanged and shrinks its
variance around them, so later elements move away from earlier ones. Because the believed
values equal the mean, only the variance needs the update, computed here by a q x q Schur
complement instead of refactorizing the n x n covariance.

With a parameter prior (``prior``, ``prior_weight``: gp/prior.py) every element maximizes
log-EI + prior_weight * log belief(x), piBO's prior-weighted acquisition in log space, the
belief the prior mixed with the uniform density (``settings.prior_share``); without
one (None) the proposal is the plain one, traced without a trace of the prior.

Everything here is pure and jitted with static shapes; run it with x64 enabled.
"""

from __future__ import annotations

import math
from functools import partial
import jax
import jax.numpy as jnp

from mjxskill.gp import gp as gpm
from mjxskill.gp.acquisition import log_ei
from mjxskill.gp.acquisition_search import maximize
from mjxskill.gp.element_scalarizations import Scalarization, element_scalarizations
from mjxskill.gp.kernels import matern52
from mjxskill.gp.prior import UnitPrior
from mjxskill.gp.prior_density import log_prior_unit
from mjxskill.gp.scalarized_posterior import normal_draws
from mjxskill.gp.settings import AcquisitionSettings

PENDING_DRAWS_SEED = 1  # the pending points' normals: a Sobol set of their own, not the candidates' (seed 0)


def standardize(s: jnp.ndarray, mask: jnp.ndarray) -> jnp.ndarray:
    """(n,) values standardized over the masked-in rows; padding rows set to 0."""
    n = jnp.maximum(jnp.sum(mask), 1)
    mu = jnp.sum(jnp.where(mask, s, 0.0)) / n
    var = jnp.sum(jnp.where(mask, (s - mu) ** 2, 0.0)) / jnp.maximum(n - 1, 1)
    sd = jnp.sqrt(jnp.where(var > 1e-18, var, 1.0))
    return jnp.where(mask, (s - mu) / sd, 0.0)


def _believer_predictor(post: gpm.GPPosterior, fantasies, fantasy_mask, deflate: bool = False, new_noise=None,
                        weights: bool = False):
    """Posterior of one GP after the Kriging believer: xs (b, d) -> mean (b,), variance (b,).

    The believed values equal the posterior mean, so the mean is that of ``post`` and only
    the variance shrinks, by a Schur complement over the q fantasies (masked-out fantasies,
    not yet chosen, contribute nothing). Each fantasy's observation noise is the fitted
    noise, plus ``new_noise`` (a scalar, the GP's standardized units) when given.

    With ``weights`` it returns (predict, chol) and predict also gives w (q, b): with the
    fantasies' values drawn as mean + chol @ e (e standard normal, (q,)), the mean of xs given
    that draw is mean + w.T @ e, its variance the one returned (conditioning on values moves
    the mean and leaves the variance).
    """
    p = post.params
    ls, os, nv = gpm.lengthscales(p), gpm.outputscale(p), gpm.noise(p)
    # Posterior covariance of the fantasies given the data, plus their observation noise.
    k_f = gpm.cross_cov(post, fantasies)  # (q, n)
    kinv_kf = k_f @ post.k_inv  # (q, n)
    fantasy_noise = nv if new_noise is None else nv + new_noise  # static branch
    s = matern52(fantasies, fantasies, ls, os) - kinv_kf @ k_f.T + fantasy_noise * jnp.eye(fantasies.shape[0])
    both = fantasy_mask[:, None] & fantasy_mask[None, :]
    s = jnp.where(both, s, jnp.eye(fantasies.shape[0]))
    s_chol = jnp.linalg.cholesky(s + gpm.JITTER * jnp.eye(fantasies.shape[0]))

    def predict(xs):
        k = gpm.cross_cov(post, xs)  # (b, n)
        mean = p.mean + k @ post.alpha
        var = os - gpm.symmetric_quadratic_form(k, post.k_inv)
        # k K^-1 k_f^T through the (n, q) product K^-1 k_f^T computed once: no second
        # (b, n) x (n, n) product (K^-1 is symmetric).
        c = matern52(xs, fantasies, ls, os) - k @ kinv_kf.T  # (b, q)
        c = jnp.where(fantasy_mask[None, :], c, 0.0)
        w = jax.scipy.linalg.solve_triangular(s_chol, c.T, lower=True)  # (q, b)
        var = var - jnp.sum(w * w, axis=0)
        if deflate:  # static
            var = var - nv
        if weights:  # static
            return mean, jnp.maximum(var, 1e-12), jnp.where(fantasy_mask[:, None], w, 0.0)
        return mean, jnp.maximum(var, 1e-12)

    return (predict, s_chol) if weights else predict


def _acquisition_for_element(post: gpm.GPPosterior, y_std, fantasies, fantasy_mask):
    """Scalarized model: log-EI of one batch element as a function of xs (b, d) -> (b,)."""
    predict = _believer_predictor(post, fantasies, fantasy_mask)
    best = jnp.min(jnp.where(post.mask, y_std, jnp.inf))

    def acq(xs):
        mean, var = predict(xs)
        val = log_ei(mean, var, best)
        return jnp.where(jnp.isnan(val), -jnp.inf, val)

    return acq


def _acquisition_per_objective(posts: gpm.GPPosterior, y_mean, y_sd, log_ei_for, fantasies, fantasy_mask,
                               deflate: bool = False, new_noise=None, pending_draws=None):
    """Per-objective model: log-EI of the element's scalarization, xs (b, d) -> (b,).

    posts: the m per-objective posteriors stacked on a leading axis, fitted to the
    objectives standardized by y_mean, y_sd (m,); log_ei_for(pending, pending_mask) -> the
    element's log-EI of (mean, var) in unstandardized units, given the pending points' values;
    new_noise: (m,) the noise variance of a new observation in each GP's standardized units,
    or None.

    pending_draws: None, the Kriging believer (the pending points at their posterior means), or
    (s, q, m) fixed standard normals: in each of the s shared draws the pending points take one
    joint posterior draw of their values, the incumbent counts that draw's values, and the
    candidate's mean is conditioned on them (qNEHVI's sequential greedy; a candidate beside a
    pending point gains nothing in the draws where that point already improves).
    """
    drawn = pending_draws is not None  # static
    built = [_believer_predictor(jax.tree.map(lambda a, i=i: a[i], posts), fantasies, fantasy_mask, deflate,
                                 None if new_noise is None else new_noise[i], weights=drawn)
             for i in range(y_mean.shape[0])]
    predictors = [b[0] for b in built] if drawn else built
    believed = jnp.stack([pr(fantasies)[0] for pr in predictors], axis=-1)  # (q, m), standardized
    if drawn:  # mean + chol @ e per draw: (s, q, m)
        pending = believed[None] + jnp.stack([pending_draws[:, :, i] @ chol.T for i, (_, chol) in enumerate(built)],
                                             axis=-1)
    else:
        pending = believed
    log_ei_of = log_ei_for(pending * y_sd + y_mean, fantasy_mask)

    def acq(xs):
        moments = [pr(xs) for pr in predictors]
        mean = jnp.stack([mo[0] for mo in moments], axis=-1) * y_sd + y_mean  # (b, m)
        var = jnp.stack([mo[1] for mo in moments], axis=-1) * y_sd**2
        if drawn:  # the mean given each draw of the pending values: mean + w.T @ e, (b, s, m)
            shift = jnp.stack([jnp.einsum("qb,sq->bs", mo[2], pending_draws[:, :, i]) for i, mo in enumerate(moments)],
                              axis=-1) * y_sd
            val = log_ei_of(mean, var, shift)
        else:
            val = log_ei_of(mean, var)
        return jnp.where(jnp.isnan(val), -jnp.inf, val)

    return acq


def prior_weighted(acq, prior: UnitPrior | None, prior_weight, share: float):
    """piBO in log space: xs -> acq(xs) + prior_weight * log belief(xs), the belief the prior
    with weight ``share`` beside the unit cube's uniform density (1) with weight 1 - share
    (``acq`` itself without a prior: None is part of the trace's structure, so this changes
    nothing then)."""
    if prior is None:  # static
        return acq
    if share >= 1.0:  # static
        return lambda xs: acq(xs) + prior_weight * log_prior_unit(prior, xs)
    log_share, log_rest = math.log(share) if share > 0.0 else -math.inf, math.log1p(-share)
    return lambda xs: acq(xs) + prior_weight * jnp.logaddexp(log_share + log_prior_unit(prior, xs), log_rest)


@partial(jax.jit, static_argnames=("q", "settings"))
def propose_batch(x, y_norm, mask, key, ref=None, prior: UnitPrior | None = None, prior_weight=0.0, obs_noise=None,
                  new_noise=None, *, q: int, settings: AcquisitionSettings = AcquisitionSettings()):
    """q new points in the unit cube.

    Args:
      x: (n, d) float64 inputs scaled to [0, 1]^d (padding rows arbitrary).
      y_norm: (n, m) float64 objectives (minimized), normalized to [0, 1] with non-finite
        values already replaced (see optimizer.py).
      mask: (n,) bool, True for real rows (at least 2 of them).
      key: PRNG key; the scalarizations and all random starts derive from it.
      ref: (m,) float64 reference point in the units of y_norm (hypervolume scalarization).
      prior: the parameter prior in unit-cube coordinates (traced arrays), or None.
      prior_weight: piBO's exponent of the prior, beta / n (a traced scalar).
      obs_noise: (n, m) float64 known noise variance of each row's value of each objective,
        in the units of y_norm (padding rows ignored), or None: none known.
      new_noise: (m,) float64 the noise variance of one new observation in the same units
        (the Kriging believer's pending points), or None: the fitted noise alone.
      Negative or non-finite noise variances are taken as 0. Both need
      ``settings.model == "per_objective"`` (ValueError otherwise).
    Returns:
      (points (q, d) float64 in [0, 1]^d, fitted GPParams).
    """
    if (obs_noise is not None or new_noise is not None) and settings.model != "per_objective":  # static
        raise ValueError(f"propose_batch: obs_noise and new_noise need model='per_objective', not {settings.model!r}")
    n, d = x.shape
    k_w, k_fit, k_acq = jax.random.split(key, 3)
    if ref is None:
        ref = jnp.ones((y_norm.shape[1],), y_norm.dtype)
    scal = element_scalarizations(y_norm, mask, ref, k_w, q, settings)
    k_fit, k_subset = jax.random.split(k_fit)
    rows = _fit_rows(mask, k_subset, settings)

    def fit(y, noise=None):
        return gpm.fit(x[rows], y[rows], mask[rows], k_fit, n_starts=settings.fit_starts, n_steps=settings.fit_steps,
                       gradient_tolerance=settings.fit_gradient_tolerance,
                       prior=settings.prior, obs_noise=None if noise is None else noise[rows])

    acq_keys = jax.random.split(k_acq, q)
    fantasies = (jnp.full((q, d), 0.5, jnp.float64), jnp.zeros((q,), bool))
    n_scal = {"scalarized": q, "per_objective": 0, "hybrid": (q + 1) // 2}[settings.model]  # static
    points = []
    params = None
    if n_scal > 0:
        fantasies, pts, params = _scalarized_points(x, mask, scal, fit, fantasies, acq_keys, n_scal, prior,
                                                    prior_weight, settings)
        points.append(pts)
    if n_scal < q:
        pts, params_o = _per_objective_points(x, mask, scal, fit, fantasies, acq_keys, range(n_scal, q), prior,
                                              prior_weight, settings, obs_noise, new_noise)
        points.append(pts)
        params = params_o if params is None else params
    return jnp.concatenate(points, axis=0), params


def _fit_rows(mask, key, settings: AcquisitionSettings):
    """The rows the hyperparameters are fitted on: every row, or, above ``fit_max_rows`` (n, static),
    a uniformly random subset of the real ones (padding rows score -inf)."""
    n = mask.shape[0]
    if n > settings.fit_max_rows:  # static
        scores = jnp.where(mask, jax.random.uniform(key, (n,)), -jnp.inf)
        _, rows = jax.lax.top_k(scores, settings.fit_max_rows)
        return rows
    return jnp.arange(n)


def _scalarized_points(x, mask, scal: Scalarization, fit, fantasies, acq_keys, n_scal: int, prior, prior_weight,
                       settings: AcquisitionSettings):
    """The batch's first ``n_scal`` points, each from a GP fitted to its own scalarization's
    values. Returns (fantasies with them added, points (n_scal, d), the GPs' parameters)."""
    d = x.shape[1]
    targets = jax.vmap(lambda s: standardize(s, mask))(scal.targets)  # (q, n)
    if x.shape[0] > settings.per_element_fit_max_rows:  # static: decided once per size bucket
        params = jax.tree.map(lambda a: jnp.broadcast_to(a, (n_scal,) + a.shape), fit(targets[0]))
    else:
        params = jax.lax.map(fit, targets[:n_scal])
    posts_s = jax.vmap(lambda p, y: gpm.condition(p, x, y, mask))(params, targets[:n_scal])

    def choose_s(carry, j):
        fant, fant_mask = carry
        post = jax.tree.map(lambda a: a[j], posts_s)
        acq = prior_weighted(_acquisition_for_element(post, targets[j], fant, fant_mask), prior, prior_weight,
                             settings.prior_share)
        xj = maximize(acq, acq_keys[j], d, settings)
        return (fant.at[j].set(xj), fant_mask.at[j].set(True)), xj

    fantasies, pts = jax.lax.scan(choose_s, fantasies, jnp.arange(n_scal))
    return fantasies, pts, params


def _per_objective_points(x, mask, scal: Scalarization, fit, fantasies, acq_keys, elements: range, prior,
                          prior_weight, settings: AcquisitionSettings, obs_noise=None, new_noise=None):
    """The batch's points ``elements`` from one GP per objective, each maximizing the log-EI of
    its scalarization of their posterior (obs_noise (n, m), new_noise (m,): known noise
    variances in y_norm's units, or None). Returns (points (len(elements), d), the GPs' parameters)."""
    d = x.shape[1]
    space = scal.space
    cnt = jnp.maximum(jnp.sum(mask), 1)
    y_mean = jnp.sum(jnp.where(mask[:, None], space, 0.0), axis=0) / cnt
    y_var = jnp.sum(jnp.where(mask[:, None], (space - y_mean) ** 2, 0.0), axis=0) / jnp.maximum(cnt - 1, 1)
    y_sd = jnp.sqrt(jnp.where(y_var > 1e-18, y_var, 1.0))
    y_std = jax.vmap(lambda col: standardize(col, mask), in_axes=1)(space)  # (m, n)
    if obs_noise is None:  # static
        params_o = jax.lax.map(fit, y_std)
        posts_o = jax.vmap(lambda p, y: gpm.condition(p, x, y, mask))(params_o, y_std)
    else:
        # Into the GPs' space (the scalarization's map, then standardization); padding rows 0.
        noise_std = jnp.where(mask[:, None], gpm.observation_noise(obs_noise) * scal.variance_factor / y_sd**2, 0.0).T
        params_o = jax.lax.map(lambda args: fit(*args), (y_std, noise_std))
        posts_o = jax.vmap(lambda p, y, v: gpm.condition(p, x, y, mask, v))(params_o, y_std, noise_std)
    if new_noise is not None:  # static
        new_noise = gpm.observation_noise(new_noise) * scal.new_variance_factor / y_sd**2
    if settings.incumbent == "posterior_mean":  # static
        # The model's own values at the observed points: a fitted noise lets its mean sit
        # below an observed optimum, and an incumbent from the observations then gives
        # re-evaluating that point an improvement that is not there.
        fitted = jax.vmap(lambda post: gpm.predict(post, x)[0])(posts_o).T * y_sd + y_mean  # (n, m)
        best = scal.incumbents(fitted, mask)
    else:
        best = scal.incumbents(space, mask)

    pending_draws = None
    if settings.pending == "draws":  # static: the shared draws' partners, a joint draw of the q pending points each
        q, m = fantasies[1].shape[0], space.shape[1]
        pending_draws = jnp.asarray(normal_draws(settings.n_draws, q * m, seed=PENDING_DRAWS_SEED)).reshape(-1, q, m)

    def choose_o(carry, j):
        fant, fant_mask = carry
        best_j = jax.tree.map(lambda a: a[j], best)
        acq = _acquisition_per_objective(posts_o, y_mean, y_sd, partial(scal.log_ei, j, best_j), fant, fant_mask,
                                         settings.variance == "deflated", new_noise, pending_draws)
        acq = prior_weighted(acq, prior, prior_weight, settings.prior_share)
        xj = maximize(acq, acq_keys[j], d, settings)
        return (fant.at[j].set(xj), fant_mask.at[j].set(True)), xj

    _, pts = jax.lax.scan(choose_o, fantasies, jnp.arange(elements.start, elements.stop))
    return pts, params_o
