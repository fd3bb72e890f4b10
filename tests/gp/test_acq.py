"""log-EI against an mpmath high-precision reference; Chebyshev scalarization and weights."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import jax
import jax.numpy as jnp
import mpmath
import numpy as np
import pytest

from mjxskill.gp.acquisition import chebyshev, log_ei, log_h, sample_simplex

mpmath.mp.dps = 60


def _log_h_reference(z: float) -> float:
    z = mpmath.mpf(z)
    return float(mpmath.log(mpmath.npdf(z) + z * mpmath.ncdf(z)))


Z = np.concatenate([-np.logspace(3, -3, 60), [0.0], np.logspace(-3, 1.3, 20)])


@pytest.fixture(scope="module")
def log_h64():
    with jax.enable_x64(True):
        f = jax.jit(log_h)
        g = jax.jit(jax.vmap(jax.grad(log_h)))
        yield lambda z: np.asarray(f(jnp.asarray(z, jnp.float64))), lambda z: np.asarray(g(jnp.asarray(z, jnp.float64)))


def test_log_h_matches_high_precision_reference_down_to_minus_1e3(log_h64):
    value, _ = log_h64
    got = value(Z)
    ref = np.array([_log_h_reference(z) for z in Z])
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12)


def test_log_h_is_finite_and_matches_asymptote_far_below(log_h64):
    value, grad = log_h64
    z = np.array([-1e5, -1e8, -1e12])
    # Asymptote phi(z)/z^2 (relative error 3/z^2) below -1/sqrt(eps).
    expected = -0.5 * z**2 - 0.5 * np.log(2 * np.pi) - 2 * np.log(-z)
    np.testing.assert_allclose(value(z), expected, rtol=1e-9)
    assert np.all(np.isfinite(grad(z)))


def test_log_h_gradient_is_finite_and_matches_reference(log_h64):
    _, grad = log_h64
    got = grad(Z)
    # d/dz log h = Phi(z) / h(z), since h'(z) = Phi(z).
    ref = np.array([float(mpmath.ncdf(z) / (mpmath.npdf(z) + z * mpmath.ncdf(z))) for z in map(mpmath.mpf, Z)])
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, ref, rtol=1e-6)


def test_log_ei_is_log_of_closed_form_expected_improvement():
    from scipy.stats import norm

    mean = np.array([0.0, 1.0, -2.0, 3.0])
    var = np.array([1.0, 0.25, 4.0, 0.01])
    best = 0.5
    sigma = np.sqrt(var)
    z = (best - mean) / sigma
    ei = sigma * (z * norm.cdf(z) + norm.pdf(z))
    with jax.enable_x64(True):
        got = np.asarray(log_ei(jnp.asarray(mean), jnp.asarray(var), best))
    np.testing.assert_allclose(got, np.log(ei), rtol=1e-10)


def test_augmented_chebyshev_formula():
    y = np.array([[0.2, 0.9], [0.5, 0.5], [1.0, 0.0]])
    w = np.array([0.3, 0.7])
    expected = np.max(y * w, axis=1) + 0.05 * np.sum(y * w, axis=1)
    with jax.enable_x64(True):
        got = np.asarray(chebyshev(jnp.asarray(y), jnp.asarray(w), 0.05))
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_flat_dirichlet_weights_lie_on_simplex_and_are_uniform():
    with jax.enable_x64(True):
        w = np.asarray(sample_simplex(jax.random.PRNGKey(0), 4000, 3))
    assert w.shape == (4000, 3)
    assert np.all(w >= 0)
    np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-12)
    # Flat Dirichlet(1,1,1): each coordinate ~ Beta(1, 2), mean 1/3, variance 1/18.
    np.testing.assert_allclose(w.mean(0), 1 / 3, atol=0.02)
    np.testing.assert_allclose(w.var(0), 1 / 18, atol=0.01)
