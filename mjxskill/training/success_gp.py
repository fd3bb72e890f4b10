"""The robust protocol's success model (``mjxskill.training.replication.choose``): a GP of the
success rate over the parameters, each row with its known noise variance, whose posterior mean
says which parameter sets a pooled batch rolls out again.

Imports jax and gp's GP at the top: ``replication`` imports this module only when it chooses
(train's --help and bad-input errors import ``replication``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjxskill.gp import gp as gpm

MODEL_BUCKET = 64  # the success model's rows are padded to a multiple of this (one compile per size)
# Its hyperparameters are fitted on a random subset of at most this many rows (the posterior
# conditions on all of them), as the optimizer's own GPs are (gp.settings fit_max_rows): a fit
# on every row of a 300-row run took 0.9 s a batch, a fifth of a push batch's episodes.
MODEL_FIT_ROWS = 128


def success_model(params: np.ndarray, rate: np.ndarray, noise: np.ndarray, bounds, key) -> np.ndarray:
    """(c,) the GP posterior mean of the success rate at ``params`` (c, P), fitted to ``rate``
    with the per-row noise variances ``noise`` (a Matern 5/2 GP on the unit cube, gp.fit's MAP
    hyperparameters on at most MODEL_FIT_ROWS of the rows; the rows padded to a multiple of
    MODEL_BUCKET)."""
    lo, hi = np.asarray(bounds, np.float64)
    n = len(params)
    size = MODEL_BUCKET * -(-n // MODEL_BUCKET)
    x = np.full((size, params.shape[1]), 0.5)
    x[:n] = (params - lo) / (hi - lo)
    mean, sd = rate.mean(), rate.std()
    sd = sd if sd > 1e-12 else 1.0
    y, obs = np.zeros(size), np.zeros(size)
    y[:n], obs[:n] = (rate - mean) / sd, noise / sd**2
    mask = np.arange(size) < n
    with jax.enable_x64(True):
        fitted = _posterior_mean_at_rows(x, y, mask, obs, key)
    return np.asarray(fitted, np.float64)[:n] * sd + mean


@jax.jit
def _posterior_mean_at_rows(x, y, mask, obs, key):
    """The fit-and-predict of ``success_model``, jitted (compiled once per padded size)."""
    k_subset, k_fit = jax.random.split(key)
    rows = jnp.arange(x.shape[0])
    if x.shape[0] > MODEL_FIT_ROWS:  # static: a random subset of the real rows (padding scores -inf)
        rows = jax.lax.top_k(jnp.where(mask, jax.random.uniform(k_subset, mask.shape), -jnp.inf), MODEL_FIT_ROWS)[1]
    params = gpm.fit(x[rows], y[rows], mask[rows], k_fit, n_starts=2, n_steps=50, prior="lognormal",
                     obs_noise=obs[rows])
    post = gpm.condition(params, x, y, mask, obs_noise=obs)
    return gpm.predict(post, x)[0]


__all__ = ["MODEL_BUCKET", "MODEL_FIT_ROWS", "success_model"]
