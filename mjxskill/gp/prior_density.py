"""The prior's log-density, the term the proposal adds to its log-EI (``mjxskill.gp.prior``
describes the prior and its piBO weighting; this is the jax side of it, jittable)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import logsumexp

from mjxskill.gp.prior import Prior, UnitPrior, unit_prior


def log_prior_unit(prior: UnitPrior, xs: jnp.ndarray) -> jnp.ndarray:
    """(b, d) points in [0, 1]^d -> (b,) log-density of the prior there (jittable)."""
    z = (xs[:, None, :] - prior.mean[None]) / prior.std[None]  # (b, K, d)
    return logsumexp(prior.log_const[None] - 0.5 * jnp.sum(z * z, axis=-1), axis=-1)


def log_density(prior: Prior, bounds, x) -> np.ndarray:
    """(b, d) points in parameter units, inside ``bounds`` -> (b,) log-density of the prior."""
    lo, hi = np.asarray(bounds, dtype=np.float64)
    u = (np.atleast_2d(np.asarray(x, dtype=np.float64)) - lo) / (hi - lo)
    with jax.enable_x64(True):
        up = jax.tree.map(jnp.asarray, unit_prior(prior, bounds))
        return np.asarray(log_prior_unit(up, jnp.asarray(u))) - np.sum(np.log(hi - lo))


__all__ = ["log_density", "log_prior_unit"]
