"""Proposal internals: the Kriging believer's Schur-complement update against refactorizing,
and the per-objective model path of the optimizer."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import jax
import jax.numpy as jnp
import numpy as np

from mjxskill.gp import AcquisitionSettings, MOBOConfig, ask, init, tell
from mjxskill.gp import gp as gpm
from mjxskill.gp.proposal import _believer_predictor


def test_believer_update_equals_conditioning_on_the_believed_points():
    rng = np.random.default_rng(0)
    x = rng.random((12, 2))
    y = np.sin(5 * x[:, 0]) + x[:, 1]
    y = (y - y.mean()) / y.std()
    mask = np.arange(12) < 9  # 3 padding rows
    fantasies = rng.random((3, 2))
    fantasy_mask = np.array([True, True, False])  # the third is not chosen yet
    xs = rng.random((5, 2))
    with jax.enable_x64(True):
        p = gpm.params_from_values([0.3, 0.5], 1.2, 1e-3, 0.1)
        post = gpm.condition(p, jnp.asarray(x), jnp.asarray(y), jnp.asarray(mask))
        mean, var = _believer_predictor(post, jnp.asarray(fantasies), jnp.asarray(fantasy_mask))(jnp.asarray(xs))
        # Reference: append the two chosen fantasies with their posterior mean as value, refactorize.
        believed, _ = gpm.predict(post, jnp.asarray(fantasies[:2]))
        x2 = np.concatenate([x[mask], fantasies[:2]])
        y2 = np.concatenate([y[mask], np.asarray(believed)])
        ref = gpm.condition(p, jnp.asarray(x2), jnp.asarray(y2), jnp.ones(len(x2), bool))
        ref_mean, ref_var = gpm.predict(ref, jnp.asarray(xs))
        _, prior_var = gpm.predict(post, jnp.asarray(xs))
    np.testing.assert_allclose(mean, ref_mean, atol=1e-8)
    np.testing.assert_allclose(var, ref_var, rtol=1e-6, atol=1e-10)
    assert np.all(np.asarray(var) <= np.asarray(prior_var) + 1e-12)


def test_per_objective_model_with_moment_matching_proposes_distinct_points_in_bounds():
    cfg = MOBOConfig(bounds=[[0.0, 0.0], [1.0, 1.0]], n_objectives=2, batch_size=3, n_init=6, seed=1,
                     acquisition=AcquisitionSettings(bucket=16, n_raw=64, n_restarts=2, n_opt_steps=5, fit_starts=1,
                                                     fit_steps=5, model="per_objective", ei="moments"))
    x = np.random.default_rng(0).random((6, 2))
    state = tell(init(cfg), x, np.stack([x[:, 0], 1 - x[:, 0] + x[:, 1] ** 2], 1))
    batch = ask(state)
    assert batch.shape == (3, 2) and np.all((batch >= 0) & (batch <= 1))
    assert np.min(np.linalg.norm(batch[:, None] - batch[None], axis=-1) + np.eye(3) * 9) > 1e-3
