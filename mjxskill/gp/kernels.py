"""Matern 5/2 covariance with one lengthscale per input dimension (ARD).

Inputs live in the unit cube (the optimizer scales them there), so lengthscales are
comparable across problems and their prior can be fixed once.
"""

from __future__ import annotations

import jax.numpy as jnp

_SQRT5 = 5.0**0.5


def matern52(x1: jnp.ndarray, x2: jnp.ndarray, lengthscales: jnp.ndarray, outputscale) -> jnp.ndarray:
    """Matern 5/2 ARD covariance matrix.

    Args:
      x1: (n1, d) inputs.
      x2: (n2, d) inputs.
      lengthscales: (d,) positive lengthscales.
      outputscale: scalar signal variance.
    Returns:
      (n1, n2) covariance ``s * (1 + sqrt5 r + 5 r^2 / 3) exp(-sqrt5 r)``, r the scaled
      Euclidean distance.
    """
    a = x1 / lengthscales
    b = x2 / lengthscales
    sq = jnp.sum(a * a, -1)[:, None] + jnp.sum(b * b, -1)[None, :] - 2.0 * a @ b.T
    sq = jnp.maximum(sq, 0.0)
    # sqrt has an infinite derivative at 0 (the diagonal); the kernel itself is smooth there,
    # so route zero distances through a safe value and patch the result.
    is_zero = sq <= 1e-30
    r = jnp.sqrt(jnp.where(is_zero, 1.0, sq))
    r = jnp.where(is_zero, 0.0, r)
    return outputscale * (1.0 + _SQRT5 * r + (5.0 / 3.0) * sq) * jnp.exp(-_SQRT5 * r)
