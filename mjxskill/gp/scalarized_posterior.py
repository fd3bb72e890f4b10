"""log-EI of the augmented Chebyshev scalarization of per-objective GP posteriors.

With one GP per objective, the objectives at a point x are independent Gaussians
f_i ~ N(mu_i, var_i) (normalized scale). Their scalarization s = cheb_w(f) is a max of
Gaussians plus a linear term, not Gaussian. Two estimates of its log-EI:
``log_ei_draws``, a quasi-Monte Carlo average of the softplus-smoothed improvement over
fixed draws (like BoTorch's qLogNParEGO; ``ei="draws"``, the default), and the analytic
log-EI of the moment-matched Gaussian N(E[s], Var[s]) from ``chebyshev_moments``
(``ei="moments"``). Where one weighted objective dominates, s is nearly linear in f and the
Gaussian is nearly exact; where two compete it keeps the max's upward shift of the mean and
its variance. The incumbent ``best`` is the caller's (``proposal.py``: the best observed
value or the best posterior mean at the observed points, ``AcquisitionSettings.incumbent``).

Both are quasi-Monte Carlo averages over one fixed set of standard normal draws
(scrambled Sobol points mapped through the normal quantile, fixed seed): the same draws at
every x and for every batch element (common random numbers), so the acquisition is
deterministic and, as an average of piecewise-linear functions of (mu, sigma), smooth
enough for gradient ascent.
"""

from __future__ import annotations

import math
from functools import lru_cache

import jax
import jax.numpy as jnp
import numpy as np
from scipy.special import ndtri
from scipy.stats import qmc

from mjxskill.gp.acquisition import chebyshev


@lru_cache(maxsize=None)
def normal_draws(num: int, m: int, seed: int = 0) -> np.ndarray:
    """(num, m) float64 quasi-random standard normal draws, centred per column.

    Centring removes the draws' sample-mean error, so E[s] is exact whenever s is linear.
    """
    return centred_normal_quantiles(qmc.Sobol(m, scramble=True, seed=seed).random(num))


def centred_normal_quantiles(u: np.ndarray) -> np.ndarray:
    """Standard normal quantiles of points u (..., m) in [0, 1)^m, centred per column over
    all of them (quasi-random draws from a Sobol set's points)."""
    z = ndtri(np.clip(u, 1e-12, 1.0 - 1e-12))
    return z - z.reshape(-1, z.shape[-1]).mean(axis=0)


def chebyshev_moments(mean: jnp.ndarray, variance: jnp.ndarray, weights: jnp.ndarray, alpha: float,
                      draws: jnp.ndarray):
    """Mean and variance of ``chebyshev(f, weights, alpha)`` for independent f_i ~ N(mean_i, variance_i).

    Args:
      mean, variance: (b, m) per-objective posterior moments at b points (normalized scale).
      weights: (m,) scalarization weights.
      draws: (s, m) standard normal draws (see :func:`normal_draws`).
    Returns:
      (mean (b,), variance (b,)) of the scalarization, estimated on the draws.
    """
    f = mean[:, None, :] + jnp.sqrt(jnp.maximum(variance, 0.0))[:, None, :] * draws[None]  # (b, s, m)
    s = chebyshev(f, weights, alpha)  # (b, s)
    s_mean = jnp.mean(s, axis=-1)
    s_var = jnp.mean((s - s_mean[:, None]) ** 2, axis=-1)
    return s_mean, s_var


def _log_softplus(u):
    """log(log(1 + exp(u))), stable: equals u where exp(u) is negligible next to 1."""
    return jnp.where(u > -30.0, jnp.log(jax.nn.softplus(jnp.maximum(u, -30.0))), u)


_LINEAR_ABOVE = 30.0  # softplus(z) = z + log1p(exp(-z)): z itself above this, to e^-30
_EXP_BELOW = -30.0  # softplus(z) = log1p(exp(z)): exp(z) itself below this, to e^-30


def log_mean_softplus(z: jnp.ndarray, axis) -> jnp.ndarray:
    """log mean(softplus(z)) over ``axis``, stable for any z, with one exp and one log1p per
    element where ``logsumexp`` of ``_log_softplus`` takes four transcendentals: a
    hypervolume acquisition evaluates it over every (direction, draw) pair at every point.

    With z' = min(z, 30) and c = max z' over the axis: softplus(z) = log1p(e^c e^(z' - c)) +
    max(z - 30, 0) to a relative e^-30; where c < -30 every term is e^z to a relative e^-30,
    so the log of the sum is c + log sum e^(z' - c). Both branches are kept finite wherever
    they are not used, so neither puts a NaN into the other's gradient; the excess over 30 is
    its own term, not z - z', whose gradient 1 - 1 would cancel two terms of 1 / sum (huge
    where every z is far below 0) and lose the gradient's precision.
    """
    capped = jnp.minimum(z, _LINEAR_ABOVE)
    c = jnp.max(capped, axis=axis, keepdims=True)
    w = jnp.exp(capped - c)  # in (0, 1]
    count = math.prod(z.shape[a] for a in ((axis,) if isinstance(axis, int) else axis))
    far = jnp.squeeze(c, axis) + jnp.log(jnp.sum(w, axis=axis))
    # where, not maximum: at c == _EXP_BELOW maximum's gradient splits in half between its arguments
    near_scale = jnp.exp(jnp.where(c >= _EXP_BELOW, c, _EXP_BELOW))
    excess = jnp.maximum(z - _LINEAR_ABOVE, 0.0)  # z - capped, without a gradient that cancels
    near = jnp.log(jnp.sum(jnp.log1p(near_scale * w) + excess, axis=axis))
    return jnp.where(jnp.squeeze(c, axis) < _EXP_BELOW, far, near) - math.log(count)


def log_ei_draws(mean: jnp.ndarray, variance: jnp.ndarray, weights: jnp.ndarray, alpha: float,
                 draws: jnp.ndarray, best, tau: float = 1e-3) -> jnp.ndarray:
    """Quasi-MC log E[max(best - chebyshev(f), 0)], the max smoothed by a softplus of width tau.

    Same inputs as :func:`chebyshev_moments`; returns (b,). The softplus (as in BoTorch's
    qLogEI) keeps a gradient where no draw improves on ``best``.
    """
    f = mean[:, None, :] + jnp.sqrt(jnp.maximum(variance, 0.0))[:, None, :] * draws[None]  # (b, s, m)
    s = chebyshev(f, weights, alpha)  # (b, s)
    log_imp = _log_softplus((best - s) / tau) + jnp.log(tau)
    return jax.scipy.special.logsumexp(log_imp, axis=-1) - jnp.log(draws.shape[0])
