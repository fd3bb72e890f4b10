"""Log expected improvement (Ament et al. 2023) and the augmented Chebyshev scalarization.

EI of a Gaussian N(mu, sigma^2) below the incumbent ``best`` (minimization) is
``sigma * h(z)`` with ``z = (best - mu) / sigma`` and ``h(z) = phi(z) + z Phi(z)``.
h(z) underflows in float64 near z = -40, where a plain log(EI) is -inf with a zero gradient;
:func:`log_h` computes log h(z) without forming h(z), so log-EI keeps a value and a gradient
far from the incumbent (its value is finite for z above about -1.3e154, where z**2 overflows).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
from jax.scipy.special import erfcx, log_ndtr

_C1 = 0.5 * math.log(2.0 * math.pi)
_C2 = 0.5 * math.log(math.pi / 2.0)
_INV_SQRT_EPS = 1.0 / math.sqrt(float(jnp.finfo(jnp.float64).eps))


def _log1mexp(x):
    """log(1 - exp(x)) for x < 0, accurate on both sides of -log 2 (Maechler 2012).

    Each branch sees its input clipped into its own side, so that neither is infinite where
    the other is chosen: x = 0 (two equal log-values) would give log1p(-1) = -inf, and the
    unchosen branch's infinite derivative times the zero cotangent `where` gives it is NaN.
    """
    near = jnp.clip(x, -math.log(2.0), -1e-300)
    far = jnp.minimum(x, -math.log(2.0))
    return jnp.where(x > -math.log(2.0), jnp.log(-jnp.expm1(near)), jnp.log1p(-jnp.exp(far)))


def log_h(z: jnp.ndarray) -> jnp.ndarray:
    """log(phi(z) + z Phi(z)), elementwise.

    Three regions as in Ament et al. (2023), eq. (9): direct for z > -1; for
    -1/sqrt(eps) < z <= -1 the exact identity h(z) = phi(z) (1 - |z| Phi(z)/phi(z)) written
    with the scaled complementary error function erfcx; below that its asymptote
    -z^2/2 - log(2 pi)/2 - 2 log|z|. Each branch is evaluated on inputs clipped into its own
    region, so the `where` that picks one never differentiates through another's NaN.

    Args:
      z: standardized improvement, any shape.
    Returns:
      log h(z), the shape of z.
    """
    z_hi = jnp.maximum(z, -1.0)
    hi = jnp.log(jnp.exp(-0.5 * z_hi**2 - _C1) + z_hi * jnp.exp(log_ndtr(z_hi)))
    z_mid = jnp.clip(z, -_INV_SQRT_EPS, -1.0)
    mid = -0.5 * z_mid**2 - _C1 + _log1mexp(jnp.log(erfcx(-z_mid / math.sqrt(2.0)) * jnp.abs(z_mid)) + _C2)
    z_lo = jnp.minimum(z, -_INV_SQRT_EPS)
    lo = -0.5 * z_lo**2 - _C1 - 2.0 * jnp.log(jnp.abs(z_lo))
    return jnp.where(z > -1.0, hi, jnp.where(z > -_INV_SQRT_EPS, mid, lo))


def log_ei(mean: jnp.ndarray, variance: jnp.ndarray, best) -> jnp.ndarray:
    """log E[max(best - f, 0)] for f ~ N(mean, variance) (minimization), elementwise.

    Args:
      mean, variance: posterior moments, broadcastable shapes (the variance is floored at
        1e-24 so that sigma > 0).
      best: the incumbent, a scalar or broadcastable to mean.
    Returns:
      log-EI, the broadcast shape.
    """
    sigma = jnp.sqrt(jnp.maximum(variance, 1e-24))
    z = (best - mean) / sigma
    return log_h(z) + jnp.log(sigma)


def chebyshev(y_normalized: jnp.ndarray, weights: jnp.ndarray, alpha: float = 0.05) -> jnp.ndarray:
    """Augmented Chebyshev scalarization ``max_i w_i y_i + alpha sum_i w_i y_i``.

    Args:
      y_normalized: (..., m) objectives to minimize, normalized to [0, 1].
      weights: (m,) nonnegative weights summing to 1.
    Returns:
      (...,) scalarized values, lower is better.
    """
    wy = y_normalized * weights
    return jnp.max(wy, axis=-1) + alpha * jnp.sum(wy, axis=-1)


def sample_simplex(key, num: int, m: int) -> jnp.ndarray:
    """(num, m) weights from the flat Dirichlet (uniform on the probability simplex)."""
    return jax.random.dirichlet(key, jnp.ones((m,), jnp.float64), (num,))
