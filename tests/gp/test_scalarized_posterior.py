"""Moments and EI of the augmented Chebyshev scalarization of independent Gaussian objectives,
against plain numpy Monte Carlo with independent pseudo-random draws."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjxskill.gp.scalarized_posterior import chebyshev_moments, log_ei_draws, normal_draws


def numpy_chebyshev(f, w, alpha):
    wf = f * w
    return wf.max(-1) + alpha * wf.sum(-1)


@pytest.mark.parametrize("m", [2, 3])
def test_moments_match_numpy_monte_carlo(m):
    rng = np.random.default_rng(m)
    b = 6
    mean = rng.uniform(0.0, 1.0, (b, m))
    var = rng.uniform(0.0, 0.1, (b, m)) ** 2 * 10
    var[0] = 0.0  # a point without uncertainty: the scalarization of the mean, exactly
    w = rng.dirichlet(np.ones(m))
    f = mean[:, None] + np.sqrt(var)[:, None] * rng.standard_normal((b, 100_000, m))
    s = numpy_chebyshev(f, w, 0.05)
    with jax.enable_x64(True):
        mu, v = chebyshev_moments(jnp.asarray(mean), jnp.asarray(var), jnp.asarray(w), 0.05,
                                  jnp.asarray(normal_draws(4096, m)))
        mu, v = np.asarray(mu), np.asarray(v)
    np.testing.assert_allclose(mu, s.mean(1), atol=4e-3)
    np.testing.assert_allclose(v, s.var(1), rtol=5e-2, atol=1e-6)
    np.testing.assert_allclose(mu[0], numpy_chebyshev(mean[0], w, 0.05), atol=1e-12)
    assert v[0] == pytest.approx(0.0, abs=1e-15)


def test_draws_are_deterministic_and_centred():
    a, b = normal_draws(128, 2), normal_draws(128, 2)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a.mean(0), 0.0, atol=1e-12)
    np.testing.assert_allclose(a.std(0), 1.0, atol=0.05)


def test_log_ei_of_draws_matches_numpy_monte_carlo_and_has_a_gradient_without_improvement():
    rng = np.random.default_rng(0)
    mean = rng.uniform(0.2, 0.6, (4, 2))
    var = np.full((4, 2), 0.15**2)
    w = np.array([0.3, 0.7])
    best = 0.25
    f = mean[:, None] + np.sqrt(var)[:, None] * rng.standard_normal((4, 100_000, 2))
    ei = np.maximum(best - numpy_chebyshev(f, w, 0.05), 0.0).mean(1)
    with jax.enable_x64(True):
        draws = jnp.asarray(normal_draws(4096, 2))
        got = log_ei_draws(jnp.asarray(mean), jnp.asarray(var), jnp.asarray(w), 0.05, draws, best, tau=1e-6)
        np.testing.assert_allclose(np.exp(np.asarray(got)), ei, rtol=5e-2)
        # Far from any improvement (no draw below best) the value is finite with a finite, nonzero gradient.
        far = lambda mu: log_ei_draws(mu, jnp.full((1, 2), 1e-4), jnp.asarray(w), 0.05, draws, best, tau=1e-3)[0]
        g = jax.grad(far)(jnp.full((1, 2), 5.0))
        assert np.isfinite(float(far(jnp.full((1, 2), 5.0))))
        assert np.all(np.isfinite(np.asarray(g))) and np.all(np.asarray(g) < 0)
