"""Hypervolume scalarizations: their average over random directions against the exact
hypervolume (Monte Carlo, stated tolerance), the extension below 0, the quasi-MC log-EI
against numpy Monte Carlo, the rescaling, and the inferred reference point."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from mjxskill.gp import hypervolume
from mjxskill.gp import hypervolume_scalarization as hvs
from mjxskill.gp.scalarized_posterior import normal_draws


def numpy_scalarization(u, lam):
    """s_lambda(u) = min_i (max(0, 1 - u_i) / lambda_i)^m, reference point at 1 (numpy)."""
    return np.min(np.maximum(0.0, 1.0 - u) / lam, axis=-1) ** u.shape[-1]


def test_constant_is_the_volume_of_the_unit_balls_positive_orthant():
    assert hvs.hypervolume_constant(2) == pytest.approx(np.pi / 4, rel=1e-14)
    assert hvs.hypervolume_constant(3) == pytest.approx(np.pi / 6, rel=1e-14)


@pytest.mark.parametrize("m", [2, 3])
def test_directions_are_uniform_on_the_positive_sphere(m):
    with jax.enable_x64(True):
        lam = np.asarray(hvs.sample_directions(jax.random.PRNGKey(m), 20_000, m))
    np.testing.assert_allclose(np.linalg.norm(lam, axis=1), 1.0, atol=1e-12)
    assert np.all(lam >= 0)
    # Uniform on the sphere: E[lambda_i] = Gamma(m/2) / (sqrt(pi) Gamma((m+1)/2)) (2/pi for m = 2,
    # 1/2 for m = 3); 5 standard errors (each coordinate's sd is below 0.5).
    expected = {2: 2 / np.pi, 3: 0.5}[m]
    np.testing.assert_allclose(lam.mean(0), expected, atol=5 * 0.5 / np.sqrt(len(lam)))


def _hv_by_scalarization(y, n=200_000, seed=0):
    """c_m * mean over random directions of max_y s_lambda(y), with its standard error."""
    m = y.shape[1]
    with jax.enable_x64(True):
        lam = np.asarray(hvs.sample_directions(jax.random.PRNGKey(seed), n, m))
    best = np.max(numpy_scalarization(y[None, :, :], lam[:, None, :]), axis=1)  # (n,)
    c = hvs.hypervolume_constant(m)
    return c * best.mean(), c * best.std() / np.sqrt(n)


@pytest.mark.parametrize(
    "front",
    [
        np.array([[0.0, 0.0]]),  # the unit square: HV 1
        np.array([[0.0, 0.6], [0.3, 0.3], [0.7, 0.0]]),
        np.array([[0.2, 0.9], [0.2, 0.9], [0.5, 0.5], [0.9, 0.1], [0.6, 0.6], [1.3, 0.0]]),  # duplicate, dominated, beyond ref
        np.array([[0.0, 0.5, 0.5], [0.5, 0.0, 0.5], [0.5, 0.5, 0.0], [0.2, 0.2, 0.9]]),
    ],
)
def test_average_over_directions_is_the_exact_hypervolume(front):
    est, se = _hv_by_scalarization(front)
    exact = hypervolume(front, np.ones(front.shape[1]))
    assert abs(est - exact) < 5 * se + 1e-12, (est, exact, se)


@settings(max_examples=15, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 6), st.integers(2, 3)), elements=st.floats(0.0, 1.2)))
def test_average_over_directions_is_the_exact_hypervolume_on_random_sets(y):
    est, se = _hv_by_scalarization(y, n=40_000, seed=len(y))
    exact = hypervolume(y, np.ones(y.shape[1]))
    assert abs(est - exact) < 5 * se + 1e-9, (est, exact, se)


def test_extended_scalarization_equals_the_clipped_one_where_positive_and_increases_beyond():
    u = np.array([[0.2, 0.5], [0.9, 0.99], [1.2, 0.1], [2.0, 3.0], [1.0, 0.0]])
    lam = np.array([0.6, 0.8])
    with jax.enable_x64(True):
        got = np.asarray(hvs.scalarize(jnp.asarray(u), jnp.asarray(lam)))
        t = np.asarray(hvs.anchored_chebyshev(jnp.asarray(u), jnp.asarray(lam)))
    ref = numpy_scalarization(u, lam)
    np.testing.assert_allclose(got[:2], ref[:2], rtol=1e-12)
    np.testing.assert_allclose(t, np.min((1 - u) / lam, axis=1), rtol=1e-12)
    assert np.all(got[2:4] < 0) and got[4] == 0.0  # beyond the reference point: negative, worse further out
    assert got[3] < got[2]


def test_log_ei_of_draws_matches_numpy_monte_carlo_and_keeps_a_gradient():
    rng = np.random.default_rng(0)
    mean = rng.uniform(0.2, 0.9, (4, 2))
    var = np.full((4, 2), 0.1**2)
    lam = np.array([0.8, 0.6])
    best = 0.35
    f = mean[:, None] + np.sqrt(var)[:, None] * rng.standard_normal((4, 200_000, 2))
    t = np.min((1 - f) / lam, axis=-1)
    s = np.where(t > 0, np.maximum(t, 0) ** 2, t)
    ei = np.maximum(s - best, 0.0).mean(1)
    with jax.enable_x64(True):
        draws = jnp.asarray(normal_draws(4096, 2))
        got = hvs.log_ei_hv_draws(jnp.asarray(mean), jnp.asarray(var), jnp.asarray(lam), draws, best, tau=1e-6)
        # 4096 quasi-random draws resolve EI to ~5 % where it is not a rare tail event (< 1e-4).
        np.testing.assert_allclose(np.exp(np.asarray(got)), ei, rtol=5e-2, atol=1e-4)
        # Beyond the reference point (every draw scalarizes below the incumbent): finite, and
        # the gradient points back towards the reference point.
        far = lambda mu: hvs.log_ei_hv_draws(mu, jnp.full((1, 2), 1e-4), jnp.asarray(lam), draws, best)[0]
        g = np.asarray(jax.grad(far)(jnp.full((1, 2), 3.0)))
        assert np.isfinite(float(far(jnp.full((1, 2), 3.0))))
        assert np.all(np.isfinite(g)) and np.all(g <= 0) and np.any(g < 0)


def test_a_shift_and_an_incumbent_per_draw_average_each_draws_own_improvement():
    """pending="draws": each shared draw s has its own mean shift (b, s, m) and incumbent
    (k, s); the estimate is the mean over draws and directions of the improvement computed in
    that draw alone (numpy, from the scalarization's definition)."""
    rng = np.random.default_rng(2)
    b, k, n_s, m = 3, 4, 5, 2
    mean, var = rng.uniform(0.2, 0.8, (b, m)), rng.uniform(0.01, 0.05, (b, m))
    lam = np.abs(rng.standard_normal((k, m)))
    lam /= np.linalg.norm(lam, axis=1, keepdims=True)
    draws = rng.standard_normal((n_s, m))
    shift = 0.1 * rng.standard_normal((b, n_s, m))
    best = rng.uniform(0.0, 0.2, (k, n_s))
    tau = 1e-3
    f = mean[:, None, None] + shift[:, None] + np.sqrt(var)[:, None, None] * draws[None, None]  # (b, 1, s, m)
    t = np.min((1 - f) / lam[None, :, None], axis=-1)  # (b, k, s)
    scal = np.where(t > 0, np.maximum(t, 0) ** m, t)
    z = (scal - best[None]) / tau
    softplus = np.maximum(z, 0) + np.log1p(np.exp(-np.abs(z)))
    expected = np.log(softplus.reshape(b, -1).mean(1)) + np.log(tau)
    with jax.enable_x64(True):
        got = hvs.log_ei_hv_draws(jnp.asarray(mean), jnp.asarray(var), jnp.asarray(lam), jnp.asarray(draws),
                                  jnp.asarray(best), tau, jnp.asarray(shift))
    np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-9, atol=1e-12)


def test_per_direction_draws_estimate_the_average_over_directions_of_each_directions_ei():
    # Several directions, each with its own incumbent: the estimate with each direction's own
    # block of draws ((k, s, m), draw_pairing="per_direction") against an independent numpy
    # Monte Carlo of the mean over directions of E[max(s_lambda(f) - best_lambda, 0)].
    rng = np.random.default_rng(1)
    mean = rng.uniform(0.2, 0.9, (3, 2))
    var = np.full((3, 2), 0.1**2)
    angles = np.linspace(0.2, 1.3, 8)
    lam = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    best = np.linspace(0.1, 0.4, 8)
    f = mean[:, None, None] + np.sqrt(var)[:, None, None] * rng.standard_normal((3, 1, 100_000, 2))
    t = np.min((1 - f) / lam[None, :, None], axis=-1)  # (b, k, s)
    s = np.where(t > 0, np.maximum(t, 0) ** 2, t)
    ei = np.maximum(s - best[None, :, None], 0.0).mean(axis=(1, 2))
    with jax.enable_x64(True):
        draws = jnp.asarray(normal_draws(8 * 1024, 2)).reshape(8, 1024, 2)
        got = hvs.log_ei_hv_draws(jnp.asarray(mean), jnp.asarray(var), jnp.asarray(lam), draws, jnp.asarray(best),
                                  tau=1e-6)
        shared = hvs.log_ei_hv_draws(jnp.asarray(mean), jnp.asarray(var), jnp.asarray(lam),
                                     jnp.asarray(normal_draws(8192, 2)), jnp.asarray(best), tau=1e-6)
    np.testing.assert_allclose(np.exp(np.asarray(got)), ei, rtol=5e-2, atol=1e-4)
    np.testing.assert_allclose(np.exp(np.asarray(shared)), ei, rtol=5e-2, atol=1e-4)


def test_reference_units_put_the_ideal_at_0_and_the_reference_at_1():
    y = np.array([[0.0, 2.0], [1.0, 1.0], [3.0, 0.5], [9.0, 9.0], [5.0, 5.0]])
    mask = np.array([True, True, True, True, False])
    with jax.enable_x64(True):
        u = np.asarray(hvs.to_reference_units(jnp.asarray(y), jnp.asarray(mask), jnp.array([4.0, 2.5])))
        # A reference point that nothing reaches yet (below the ideal): the observed range.
        u_bad = np.asarray(hvs.to_reference_units(jnp.asarray(y), jnp.asarray(mask), jnp.array([-1.0, 2.5])))
        c = np.asarray(hvs.compress_beyond_reference(jnp.array([0.5, 1.0, np.e])))
    np.testing.assert_allclose(u[:4], (y[:4] - [0.0, 0.5]) / [4.0, 2.0])
    np.testing.assert_allclose(u_bad[:4, 0], y[:4, 0] / 9.0)
    np.testing.assert_allclose(c, [0.5, 1.0, 2.0])


def test_inferred_reference_point_is_the_fronts_nadir_plus_a_margin_of_its_extent():
    y = np.array([[0.0, 4.0], [1.0, 2.0], [3.0, 0.0], [5.0, 5.0], [np.nan, -9.0]])
    np.testing.assert_allclose(hvs.reference_point(y, 0.1), [3.3, 4.4])
    # One front point: the margin is taken of the observed range.
    np.testing.assert_allclose(hvs.reference_point(np.array([[0.0, 0.0], [2.0, 1.0]]), 0.5), [1.0, 0.5])
    assert np.all(np.isnan(hvs.reference_point(np.full((2, 2), np.nan))))


def test_warmup_reference_is_the_worst_value_plus_a_margin_of_the_range():
    y = np.array([[0.0, 4.0], [1.0, np.inf], [3.0, 0.0], [np.nan, 2.0]])
    np.testing.assert_allclose(hvs.warmup_reference(y, 0.1), [3.3, 4.4])
    got = hvs.warmup_reference(np.array([[1.0, np.nan], [1.0, np.nan]]), 0.1)
    assert got[0] == pytest.approx(1.0 + 1e-10) and np.isnan(got[1])


@pytest.mark.parametrize("paired_draws", [False, True])
@pytest.mark.parametrize("m", [2, 3, 4])
def test_quasi_random_directions_are_uniform_and_cover_the_sphere_evenly(m, paired_draws):
    with jax.enable_x64(True):
        groups = np.asarray(hvs.quasi_random_directions(jax.random.PRNGKey(m), 400, 64, m, paired_draws))
    lam = groups.reshape(-1, m)
    np.testing.assert_allclose(np.linalg.norm(lam, axis=1), 1.0, atol=1e-12)
    assert np.all(lam >= 0)
    # Each direction uniform on the positive sphere (the same mean as independent directions);
    # groups are independent, so the standard error is over groups at most.
    expected = {2: 2 / np.pi, 3: 0.5, 4: 4 / (3 * np.pi)}[m]
    np.testing.assert_allclose(lam.mean(0), expected, atol=5 * 0.5 / np.sqrt(400))
    # Even cover (m = 2, 3): the hypervolume estimate of a front from one group of 64 varies far less
    # between groups than from 64 independent directions (the reason they exist).
    front = {2: np.array([[0.0, 0.6], [0.3, 0.3], [0.7, 0.0]]),
             3: np.array([[0.0, 0.5, 0.5], [0.5, 0.0, 0.5], [0.5, 0.5, 0.0]]),
             4: np.eye(4) * 0.0 + np.array([[0.0, 0.5, 0.5, 0.5], [0.5, 0.0, 0.5, 0.5], [0.5, 0.5, 0.0, 0.5],
                                             [0.5, 0.5, 0.5, 0.0]])}[m]
    with jax.enable_x64(True):
        independent = np.asarray(hvs.sample_directions(jax.random.PRNGKey(99), 400 * 64, m)).reshape(400, 64, m)

    def estimates(dirs):
        best = np.max(numpy_scalarization(front[None, None], dirs[:, :, None, :]), axis=2)  # (groups, 64)
        return hvs.hypervolume_constant(m) * best.mean(1)

    exact = hypervolume(front, np.ones(m))
    qmc_est, iid_est = estimates(groups), estimates(independent)
    assert abs(qmc_est.mean() - exact) < 5 * qmc_est.std() / np.sqrt(400) + 1e-12  # unbiased
    if m <= 3:  # area-preserving maps; above, the normal quantile's map keeps only the uniformity
        assert qmc_est.std() < 0.5 * iid_est.std()


@pytest.mark.parametrize("m", [2, 3])
@pytest.mark.parametrize("per_direction", [1, 2])
def test_paired_draws_are_standard_normal_and_independent_of_their_directions(m, per_direction):
    # Each direction's own draws must not depend on the direction: a correlation between the
    # two biases the Monte Carlo estimate towards whatever the correlated pairs score. Sobol
    # sets for each alone, scrambled alike, correlated at 0.5-0.6 after the random shift.
    k = 2048
    draws = hvs.paired_normal_draws(k, per_direction, m)
    assert draws.shape == (k, per_direction, m)
    flat = draws.reshape(-1, m)
    np.testing.assert_allclose(flat.mean(0), 0.0, atol=1e-12)
    np.testing.assert_allclose(flat.std(0), 1.0, atol=0.02)
    assert np.all(np.abs(np.corrcoef(flat.T)[np.triu_indices(m, 1)]) < 0.02)
    for seed in range(4):
        with jax.enable_x64(True):
            lam = np.asarray(hvs.quasi_random_directions(jax.random.PRNGKey(seed), 1, k, m, paired_draws=True))[0]
        for t in range(per_direction):
            cross = np.corrcoef(np.c_[lam, draws[:, t]].T)[:m, m:]
            assert np.all(np.abs(cross) < 0.03), (seed, t, cross)


@settings(deadline=None, max_examples=60)
@given(st.floats(-3000.0, 3000.0), st.floats(0.0, 60.0), st.integers(0, 2**32 - 1))
@example(-30.0, 0.0, 0)  # every z at the switch between the two forms (where a maximum's gradient splits)
@example(30.0, 0.0, 0)  # every z where the softplus turns linear
def test_log_mean_softplus_is_exact_with_its_gradient_in_every_regime(shift, scale, seed):
    import mpmath as mp

    from mjxskill.gp.scalarized_posterior import log_mean_softplus

    z = np.random.default_rng(seed).normal(size=(3, 16)) * scale + shift
    mp.mp.dps = 40
    values = [[mp.log1p(mp.exp(mp.mpf(float(v)))) for v in row] for row in z]
    sums = [mp.fsum(row) for row in values]
    want = np.array([float(mp.log(s / z.shape[1])) for s in sums])
    # d/dz_i log sum softplus = sigmoid(z_i) / sum softplus
    want_grad = np.array([[float(mp.exp(mp.mpf(float(v)) - mp.log1p(mp.exp(mp.mpf(float(v))))) / s) for v in row]
                          for row, s in zip(z, sums)])
    with jax.enable_x64(True):
        got = np.asarray(log_mean_softplus(jnp.asarray(z), axis=-1))
        grad = np.asarray(jax.grad(lambda v: jnp.sum(log_mean_softplus(v, axis=-1)))(jnp.asarray(z)))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    big = want_grad > 1e-280  # gradients that float64 holds without underflow
    np.testing.assert_allclose(grad[big], want_grad[big], rtol=1e-9)
    assert np.all(np.abs(grad[~big]) < 1e-270)


@settings(max_examples=40, deadline=None)
@given(u=arrays(np.float64, (9, 3), elements=st.sampled_from([0.0, 0.1, 0.25, 0.5, 0.8, 1.0, 1.6, 3.0])),
       n_masked=st.integers(1, 9), margin=st.sampled_from([0.0, 0.1, 0.5]))
def test_front_reference_is_the_inferred_reference_point_within_the_runs(u, n_masked, margin):
    """The jitted front reference against the host-side reference_point (BoTorch's rule):
    nadir plus a margin of the extent, the observed range where the front has none; at most 1.
    Values from a small grid, so ties, duplicates and one-point fronts come up."""
    mask = np.arange(9) < n_masked
    with jax.enable_x64(True):
        got = np.asarray(jax.jit(hvs.front_reference, static_argnums=2)(jnp.asarray(u), jnp.asarray(mask), margin))
    want = np.clip(hvs.reference_point(u[mask], margin), 1e-6, 1.0)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
