"""Exact GP regression in float64: marginal-likelihood fit with priors, and conditioning.

The training set has a static, padded size (see ``optimizer.py``): rows whose ``mask`` is
False are padding. Padding rows get an identity block in the covariance and a zero target,
so they add nothing to the log-determinant or the quadratic form, and every shape stays
constant while the data grows (no recompiles within a size bucket).

Observation noise: every real row has the fitted homoscedastic noise variance ``noise(p)``
(a learned nugget, for model misfit and unknown noise) and, when ``obs_noise`` (n,) is given,
its own known noise variance on top (a row that is the mean of several noisy evaluations:
BoTorch's fixed-noise GP with a learned nugget beside it). ``obs_noise`` is data, not a
hyperparameter; None is a static branch that computes exactly what a GP without it does.
:func:`predict` is always the latent (noise-free) posterior.

Conventions: inputs are scaled to the unit cube, targets standardized (zero mean, unit
variance over the real rows). Hyperparameters are log-parameterized above a floor, with the
Gamma priors BoTorch used for Matern 5/2 GPs on such data before its 0.12 (lengthscale
Gamma(3, 6), outputscale Gamma(2, 0.15), noise variance Gamma(1.1, 0.05)), or the
dimension-scaled LogNormal lengthscale prior in their place, or BoTorch's default since 0.12
(that lengthscale prior, the outputscale held at 1, noise LogNormal(-4, 1)) (:func:`log_prior`).

All functions expect float64 arrays and must run with x64 enabled (``jax.enable_x64(True)``);
they do not switch it on themselves so that the rest of the process stays float32.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import optax

from mjxskill.gp.kernels import matern52

LENGTHSCALE_FLOOR = 1e-2  # in unit-cube coordinates
NOISE_FLOOR = 1e-6  # noise variance, standardized units; noiseless data sits at the floor
OUTPUTSCALE_FLOOR = 1e-4
JITTER = 1e-8  # ~sqrt(float64 eps), added to the diagonal before Cholesky


class GPParams(NamedTuple):
    """Unconstrained GP hyperparameters (value = floor + exp(raw))."""

    raw_lengthscales: jnp.ndarray  # (d,) float64
    raw_outputscale: jnp.ndarray  # () float64
    raw_noise: jnp.ndarray  # () float64
    mean: jnp.ndarray  # () float64, constant prior mean


class GPPosterior(NamedTuple):
    """What prediction needs: the training set and its factorized covariance."""

    params: GPParams
    x: jnp.ndarray  # (n, d) float64 training inputs (padding rows arbitrary)
    mask: jnp.ndarray  # (n,) bool, True for real rows
    chol: jnp.ndarray  # (n, n) float64 lower Cholesky factor of K + diag(noise + obs_noise) (padded)
    k_inv: jnp.ndarray  # (n, n) float64 inverse of the same matrix, padding rows zeroed
    alpha: jnp.ndarray  # (n,) float64 k_inv @ (y - mean)


def lengthscales(p: GPParams) -> jnp.ndarray:
    """(d,) lengthscales, in unit-cube coordinates."""
    return LENGTHSCALE_FLOOR + jnp.exp(p.raw_lengthscales)


def outputscale(p: GPParams) -> jnp.ndarray:
    """() signal variance, in standardized units."""
    return OUTPUTSCALE_FLOOR + jnp.exp(p.raw_outputscale)


def noise(p: GPParams) -> jnp.ndarray:
    """() noise variance, in standardized units."""
    return NOISE_FLOOR + jnp.exp(p.raw_noise)


def params_from_values(ls, os, nv, mean=0.0) -> GPParams:
    """Raw parameters for given constrained values: lengthscales ``ls`` (d,), outputscale
    ``os``, noise variance ``nv`` (each above its floor) and constant mean ``mean``."""
    f64 = lambda v: jnp.asarray(v, jnp.float64)
    return GPParams(
        raw_lengthscales=jnp.log(f64(ls) - LENGTHSCALE_FLOOR),
        raw_outputscale=jnp.log(f64(os) - OUTPUTSCALE_FLOOR),
        raw_noise=jnp.log(f64(nv) - NOISE_FLOOR),
        mean=f64(mean),
    )


def default_params(d: int) -> GPParams:
    """Where every fit starts: lengthscales 1/3 (the mode of their Gamma(3, 6) prior),
    outputscale 1 (the standardized targets' variance), noise variance 1e-3, mean 0."""
    return params_from_values(jnp.full((d,), 1.0 / 3.0), 1.0, 1e-3)


# Each hyperparameter prior as its three parts: the lengthscales' prior ("gamma": Gamma(3, 6);
# "lognormal": the dimension-scaled LogNormal), whether the outputscale is held at 1 (no term; else
# Gamma(2, 0.15)), and the noise variance's prior ("gamma": Gamma(1.1, 0.05); "lognormal":
# LogNormal(-4, 1)). What each is for: ``log_prior``.
PRIORS = {
    "gamma": ("gamma", False, "gamma"),
    "lognormal": ("lognormal", False, "gamma"),
    "dim_scaled": ("lognormal", True, "lognormal"),
    "small_noise": ("lognormal", False, "lognormal"),
    "unit_outputscale": ("lognormal", True, "gamma"),
}
# The priors whose fit holds the outputscale at 1, the standardized targets' variance.
UNIT_OUTPUTSCALE = tuple(name for name, (_, held, _) in PRIORS.items() if held)


def _gamma_logpdf(x, concentration, rate):
    return jax.scipy.stats.gamma.logpdf(x, concentration, scale=1.0 / rate)


def _lognormal_logpdf(x, loc, scale):
    return jax.scipy.stats.norm.logpdf(jnp.log(x), loc, scale) - jnp.log(x)


def log_prior(p: GPParams, prior: str = "gamma") -> jnp.ndarray:
    """Log-density of the constrained hyperparameters (scalar).

    prior: "gamma", the Gamma priors above on every hyperparameter; "lognormal", the
    lengthscales' replaced by the dimension-scaled LogNormal(sqrt(2) + log(d) / 2, sqrt(3))
    of Hvarfner et al. (2024), BoTorch's default since 0.12, whose heavy right tail lets a
    smooth objective keep long lengthscales as d grows; "dim_scaled", all of BoTorch's
    default since 0.12: that lengthscale prior, no outputscale (:func:`fit` holds it at 1, the
    standardized targets' variance) and the noise variance's LogNormal(-4, 1); "small_noise",
    "lognormal" with that noise prior instead of the Gamma(1.1, 0.05), the outputscale fitted;
    "unit_outputscale", "lognormal" with the outputscale held at 1 (no term), the noise's Gamma kept.
    """
    lengthscale_prior, outputscale_held, noise_prior = PRIORS[prior]  # static
    ls = lengthscales(p)
    if lengthscale_prior == "lognormal":
        d = ls.shape[0]
        total = jnp.sum(_lognormal_logpdf(ls, math.sqrt(2.0) + 0.5 * math.log(d), math.sqrt(3.0)))
    else:
        total = jnp.sum(_gamma_logpdf(ls, 3.0, 6.0))
    if not outputscale_held:  # held at 1 by :func:`fit`: no term
        total = total + _gamma_logpdf(outputscale(p), 2.0, 0.15)
    if noise_prior == "lognormal":
        return total + _lognormal_logpdf(noise(p), -4.0, 1.0)
    return total + _gamma_logpdf(noise(p), 1.1, 0.05)


def observation_noise(obs_noise: jnp.ndarray) -> jnp.ndarray:
    """(n,) known noise variances made safe to add to a covariance diagonal: negative and
    non-finite entries (a caller's bug) become 0."""
    return jnp.where(jnp.isfinite(obs_noise) & (obs_noise > 0.0), obs_noise, 0.0)


def _padded_cov(p: GPParams, x, mask, obs_noise=None):
    """(n, n) K + diag(noise + obs_noise + jitter) on real rows, identity on padding rows
    (obs_noise (n,) or None: none)."""
    k = matern52(x, x, lengthscales(p), outputscale(p))
    both = mask[:, None] & mask[None, :]
    eye = jnp.eye(x.shape[0], dtype=x.dtype)
    diag = noise(p) + JITTER
    if obs_noise is not None:  # static
        diag = diag + observation_noise(obs_noise)
    return jnp.where(both, k, 0.0) + eye * jnp.where(mask, diag, 1.0)


def log_marginal_likelihood(p: GPParams, x, y, mask, obs_noise=None) -> jnp.ndarray:
    """log N(y | mean, K + diag(noise + obs_noise)) over the real rows (scalar), with a cheap
    gradient.

    Args: x (n, d), y (n,), mask (n,) bool, obs_noise (n,) known noise variances or None.

    The value is the usual Cholesky form. Its gradient is the closed form
    dL/dC = 0.5 (a a^T - C^-1) contracted with dC, dL/dmean = sum(a), a = C^-1 (y - mean),
    C the covariance, attached through a surrogate with the same gradient, because
    reverse-mode autodiff through the Cholesky factorization costs several times more on a CPU
    (benchmarks/RESULTS.md, "Figures once quoted in mjxskill/gp's comments"). The surrogate
    holds C itself, so the gradient is right for any part of C: the hyperparameters' (obs_noise
    is data; its own gradient, unused, is right too).
    """
    cov = _padded_cov(p, x, mask, obs_noise)
    chol = jnp.linalg.cholesky(cov)
    r = jnp.where(mask, y - p.mean, 0.0)
    w = jsl.solve_triangular(chol, r, lower=True)
    n = jnp.sum(mask)
    value = -0.5 * w @ w - jnp.sum(jnp.log(jnp.diag(chol))) - 0.5 * n * jnp.log(2.0 * jnp.pi)
    k_inv = jsl.cho_solve((chol, True), jnp.eye(x.shape[0], dtype=x.dtype))
    a = k_inv @ r
    weight = jax.lax.stop_gradient(0.5 * (jnp.outer(a, a) - k_inv))
    surrogate = jnp.sum(weight * cov) + p.mean * jax.lax.stop_gradient(jnp.sum(a))
    return jax.lax.stop_gradient(value - surrogate) + surrogate


def fit_loss(p: GPParams, x, y, mask, prior: str = "gamma", obs_noise=None) -> jnp.ndarray:
    """Negative (log marginal likelihood + log prior) per real row; NaN mapped to +inf."""
    n = jnp.maximum(jnp.sum(mask), 1)
    loss = -(log_marginal_likelihood(p, x, y, mask, obs_noise) + log_prior(p, prior)) / n
    return jnp.where(jnp.isfinite(loss), loss, jnp.inf)


def fit(x, y, mask, key, *, n_starts: int = 3, n_steps: int = 50, prior: str = "gamma",
        obs_noise=None, gradient_tolerance: float = 0.0) -> GPParams:
    """MAP hyperparameters by ``n_steps`` L-BFGS steps from ``n_starts`` starts:
    :func:`default_params` and ``n_starts - 1`` random lengthscales. With
    ``gradient_tolerance`` > 0 a start stops earlier, once the loss's gradient (2-norm over the
    raw parameters) falls below it.

    Args:
      x: (n, d) float64 unit-cube inputs; y: (n,) float64 standardized targets;
      mask: (n,) bool real rows; key: PRNG key for the random starts;
      prior: the hyperparameter prior (see :func:`log_prior`);
      obs_noise: (n,) float64 known noise variance of each row (standardized units), added to
        the fitted noise, or None.
    Returns:
      GPParams of the start with the lowest final loss.
    """
    d = x.shape[1]
    base = default_params(d)
    # Random starts: lengthscales log-uniform over [0.05, 2], the rest as in default_params.
    n_rand = n_starts - 1
    rand_ls = jnp.exp(jax.random.uniform(key, (n_rand, d), jnp.float64, jnp.log(0.05), jnp.log(2.0)))
    starts = jax.tree.map(
        lambda b: jnp.broadcast_to(b, (n_starts,) + b.shape), base
    )._replace(
        raw_lengthscales=jnp.concatenate(
            [base.raw_lengthscales[None], jnp.log(rand_ls - LENGTHSCALE_FLOOR)], axis=0
        )
    )
    if prior in UNIT_OUTPUTSCALE:  # static: no outputscale, it is 1 (the loss does not see the parameter)
        loss = lambda p: fit_loss(p._replace(raw_outputscale=base.raw_outputscale), x, y, mask, prior, obs_noise)
    else:
        loss = lambda p: fit_loss(p, x, y, mask, prior, obs_noise)
    opt = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(loss)

    def run(p0):
        def step(carry, _):
            p, s = carry
            value, grad = value_and_grad(p, state=s)
            # A NaN gradient (numerical breakdown) would poison L-BFGS's memory: stop there.
            ok = jnp.isfinite(value)
            for g in jax.tree.leaves(grad):
                ok = ok & jnp.all(jnp.isfinite(g))
            grad = jax.tree.map(lambda g: jnp.where(ok, g, 0.0), grad)
            updates, s_new = opt.update(grad, s, p, value=value, grad=grad, value_fn=loss)
            p_new = optax.apply_updates(p, updates)
            p_new = jax.tree.map(lambda a, b: jnp.where(ok, a, b), p_new, p)
            return (p_new, s_new), None

        if gradient_tolerance > 0.0:  # static
            # The state's gradient is that of the last point L-BFGS's line search evaluated, the
            # current one; a NaN step zeroes it, which stops the start there too.
            def going(carry):
                _, s = carry
                count = optax.tree_utils.tree_get(s, "count")
                return (count == 0) | ((count < n_steps) & (optax.tree_utils.tree_norm(
                    optax.tree_utils.tree_get(s, "grad")) >= gradient_tolerance))

            p, _ = jax.lax.while_loop(going, lambda carry: step(carry, None)[0], (p0, opt.init(p0)))
        else:
            (p, _), _ = jax.lax.scan(step, (p0, opt.init(p0)), None, length=n_steps)
        return p, loss(p)

    # lax.map, not vmap: under vmap the line search's lax.cond becomes a select that runs every
    # branch, which makes the fit many times slower on a CPU.
    finals, losses = jax.lax.map(run, starts)
    best = jnp.argmin(losses)
    fitted = jax.tree.map(lambda a: a[best], finals)
    return fitted._replace(raw_outputscale=base.raw_outputscale) if prior in UNIT_OUTPUTSCALE else fitted


def condition(p: GPParams, x, y, mask, obs_noise=None) -> GPPosterior:
    """Conditions the GP with hyperparameters ``p`` on x (n, d), y (n,), mask (n,) bool, with
    obs_noise (n,) the rows' known noise variances (or None): the training covariance is
    factorized once here for every later :func:`predict`."""
    cov = _padded_cov(p, x, mask, obs_noise)
    chol = jnp.linalg.cholesky(cov)
    k_inv = jsl.cho_solve((chol, True), jnp.eye(x.shape[0], dtype=x.dtype))
    both = mask[:, None] & mask[None, :]
    k_inv = jnp.where(both, k_inv, 0.0)
    alpha = k_inv @ jnp.where(mask, y - p.mean, 0.0)
    return GPPosterior(p, x, mask, chol, k_inv, alpha)


def cross_cov(post: GPPosterior, xs: jnp.ndarray) -> jnp.ndarray:
    """(b, n) prior covariance between test points xs (b, d) and the real training rows."""
    k = matern52(xs, post.x, lengthscales(post.params), outputscale(post.params))
    return jnp.where(post.mask[None, :], k, 0.0)


@jax.custom_vjp
def symmetric_quadratic_form(k: jnp.ndarray, a: jnp.ndarray) -> jnp.ndarray:
    """(b,) rows of diag(k a k^T) for (b, n) k and a symmetric (n, n) a (the posterior
    variance's k K^-1 k^T).

    Its gradient in k is 2 (k a) g, the product the value already computed: autodiff, which
    cannot know that a is symmetric, would multiply by a^T once more, a second (b, n) x (n, n)
    product in every acquisition gradient step (benchmarks/RESULTS.md, "Hypervolume
    scalarizations, per-objective GPs", Overhead).
    """
    return jnp.sum((k @ a) * k, axis=-1)


def _quadratic_form_fwd(k, a):
    ka = k @ a
    return jnp.sum(ka * k, axis=-1), (k, ka)


def _quadratic_form_bwd(residuals, g):
    k, ka = residuals
    gk = g[:, None] * k
    # The cotangent of a (unused by the acquisition's gradient, so compiled away there).
    return 2.0 * g[:, None] * ka, gk.T @ k


symmetric_quadratic_form.defvjp(_quadratic_form_fwd, _quadratic_form_bwd)


def predict(post: GPPosterior, xs: jnp.ndarray):
    """Posterior mean (b,) and latent variance (b,) at xs (b, d), noise excluded."""
    k = cross_cov(post, xs)
    mean = post.params.mean + k @ post.alpha
    var = outputscale(post.params) - symmetric_quadratic_form(k, post.k_inv)
    return mean, jnp.maximum(var, 1e-12)
