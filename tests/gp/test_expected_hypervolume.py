"""The closed-form expected hypervolume improvement against the exact hypervolume
(``mjxskill.gp.hypervolume``): the improvement of a (nearly) certain point for any point set
(hypothesis), numpy Monte Carlo over the posterior, and a finite value and gradient where it
underflows or where cells have no width."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays
from scipy.special import ndtr

from mjxskill.gp import expected_hypervolume as ehv
from mjxskill.gp import hypervolume
from mjxskill.gp.acquisition import _log1mexp


def _improvement(points, f):
    """The exact hypervolume improvement of f over points about the reference point 1."""
    m = len(f)
    inside = points[np.all(points < 1.0, axis=1)]
    if not np.all(f < 1.0):
        return 0.0
    before = hypervolume(inside, np.ones(m)) if len(inside) else 0.0
    return hypervolume(np.r_[inside, f[None]], np.ones(m)) - before


def _log_ehvi(mean, variance, points):
    with jax.enable_x64(True):
        cells = ehv.grid(jnp.asarray(points, jnp.float64))
        return np.asarray(ehv.log_expected_improvement(jnp.asarray(mean, jnp.float64),
                                                       jnp.asarray(variance, jnp.float64), cells))


# Coordinates on a coarse grid so that repeated values (cells of no width), duplicate and
# dominated points occur; some beyond the reference point (1).
_coordinates = st.sampled_from(np.round(np.arange(-0.2, 1.25, 0.1), 1).tolist())


@pytest.mark.parametrize("m", [2, 3])
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_a_certain_point_gains_the_exact_hypervolume_improvement(m, data):
    n = data.draw(st.integers(1, 7))
    points = data.draw(arrays(np.float64, (n, m), elements=_coordinates))
    f = data.draw(arrays(np.float64, (m,), elements=st.floats(-0.3, 1.2)))
    got = np.exp(_log_ehvi(f[None], np.full((1, m), 1e-24), points))[0]
    # sd 1e-12: the expectation is the improvement itself up to ~1e-12 per unit of volume.
    assert got == pytest.approx(_improvement(points, f), abs=1e-9)


@pytest.mark.parametrize("m", [2, 3])
def test_expectation_matches_monte_carlo_over_the_region(m):
    """By Fubini, E[improvement] = the integral over the undominated part of the box below 1
    of P(f <= u) = prod_i Phi((u_i - mean_i) / sd_i): a uniform Monte Carlo integral over u,
    independent of the grid."""
    rng = np.random.default_rng(m)
    points = rng.uniform(0.1, 1.05, (7, m))
    points = np.r_[points, points[:1], np.ones((2, m))]  # a duplicate and two padding rows
    mean = rng.uniform(0.0, 0.9, (3, m))
    sd = rng.uniform(0.02, 0.3, (3, m))
    got = np.exp(_log_ehvi(mean, sd**2, points))
    inside = points[np.all(points < 1.0, axis=1)]
    for b in range(3):
        low = mean[b] - 8.0 * sd[b]  # P(f_i <= u_i) < 1e-15 below
        u = low + (1.0 - low) * rng.random((400_000, m))
        undominated = ~np.any(np.all(inside[None] <= u[:, None], axis=-1), axis=1)
        integrand = undominated * np.prod(ndtr((u - mean[b]) / sd[b]), axis=1) * np.prod(1.0 - low)
        assert abs(got[b] - integrand.mean()) < 5 * integrand.std() / np.sqrt(len(u)), b


def test_log_value_and_gradient_stay_finite_far_away_and_on_repeated_coordinates():
    # Repeated coordinates make cells of no width (log 0, masked); a nearly deterministic
    # objective puts its expectations deep in log_h's asymptotic branch.
    points = np.array([[0.2, 0.5, 0.3], [0.2, 0.4, 0.6], [0.5, 0.2, 0.3], [0.5, 0.2, 0.3], [1.0, 1.0, 1.0]])
    with jax.enable_x64(True):
        cells = ehv.grid(jnp.asarray(points))
        for mean, var in (([0.3, 0.3, 0.3], [1e-15, 1e-4, 1e-4]), ([3.0, 3.0, 3.0], [1e-4] * 3),
                          ([0.6, 0.6, 0.6], [1e-6] * 3)):  # near, beyond the reference, dominated
            mean, var = jnp.asarray([mean]), jnp.asarray([var])
            value, grads = jax.value_and_grad(lambda mu, v: ehv.log_expected_improvement(mu, v, cells)[0],
                                              argnums=(0, 1))(mean, var)
            assert np.isfinite(float(value))
            assert np.all(np.isfinite(np.asarray(grads[0]))) and np.all(np.isfinite(np.asarray(grads[1])))
    # Dominated and far beyond: the expectation underflows, its logarithm orders them.
    far = _log_ehvi(np.array([[0.6, 0.6, 0.6], [0.8, 0.8, 0.8]]), np.full((2, 3), 1e-6), points)
    assert np.all(np.isfinite(far)) and far[0] > far[1]


def test_log1mexp_has_a_finite_gradient_at_zero():
    with jax.enable_x64(True):
        g = jax.grad(lambda x: jnp.where(x < 0.0, _log1mexp(x), 0.0))(jnp.float64(0.0))
        assert np.isfinite(float(g))
        np.testing.assert_allclose(float(_log1mexp(jnp.float64(-1.0))), np.log1p(-np.exp(-1.0)), rtol=1e-14)
        np.testing.assert_allclose(float(_log1mexp(jnp.float64(-1e-3))), np.log(-np.expm1(-1e-3)), rtol=1e-14)


def test_more_than_three_objectives_are_refused():
    with pytest.raises(ValueError, match="2 or 3 objectives, got 4"):
        ehv.grid(jnp.zeros((3, 4)))


def test_a_grid_on_the_non_dominated_points_alone_gives_the_same_expectation():
    rng = np.random.default_rng(5)
    front = rng.dirichlet(np.ones(3), 6) * 0.8  # mutually non-dominated
    behind = front[rng.integers(0, 6, 20)] + rng.uniform(0.0, 0.1, (20, 3))  # each dominated by a front point
    points = rng.permutation(np.r_[behind, front, np.ones((4, 3))])
    mean, var = rng.uniform(0.0, 0.6, (5, 3)), np.full((5, 3), 1e-3)
    with jax.enable_x64(True):
        full = ehv.log_expected_improvement(jnp.asarray(mean), jnp.asarray(var), ehv.grid(jnp.asarray(points)))
        small = ehv.log_expected_improvement(jnp.asarray(mean), jnp.asarray(var), ehv.grid(jnp.asarray(points), 8))
    assert ehv.grid(jnp.asarray(points), 8).level.shape == (9, 9)
    np.testing.assert_allclose(np.asarray(small), np.asarray(full), rtol=1e-12)
