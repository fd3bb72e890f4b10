"""GP posterior against a dense float64 numpy closed form; hyperparameter recovery; x64 scoping."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import jax
import jax.flatten_util
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.stats import multivariate_normal

from mjxskill.gp import gp as gpm
from mjxskill.gp.kernels import matern52


def _matern52_numpy(a, b, ls, s):
    r = np.sqrt(np.sum(((a[:, None, :] - b[None, :, :]) / ls) ** 2, axis=-1))
    return s * (1 + np.sqrt(5) * r + 5 * r**2 / 3) * np.exp(-np.sqrt(5) * r)


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    x = rng.random((24, 3))
    y = np.sin(4 * x[:, 0]) + x[:, 1] ** 2 - x[:, 2]
    return x, (y - y.mean()) / y.std()


def test_kernel_matches_numpy():
    rng = np.random.default_rng(1)
    a, b, ls = rng.random((5, 3)), rng.random((4, 3)), np.array([0.2, 0.5, 1.5])
    with jax.enable_x64(True):
        got = np.asarray(matern52(jnp.asarray(a), jnp.asarray(b), jnp.asarray(ls), 1.7))
    np.testing.assert_allclose(got, _matern52_numpy(a, b, ls, 1.7), rtol=1e-12)


def test_posterior_matches_closed_form_with_padding(data):
    x, y = data
    ls, s, nv, mean = np.array([0.3, 0.6, 0.9]), 1.3, 1e-3, 0.1
    xs = np.random.default_rng(2).random((7, 3))
    # Pad with 8 garbage rows: they must not change anything.
    xp = np.concatenate([x, np.full((8, 3), 123.0)])
    yp = np.concatenate([y, np.full(8, -1e3)])
    mask = np.arange(len(xp)) < len(x)
    with jax.enable_x64(True):
        p = gpm.params_from_values(ls, s, nv, mean)
        post = gpm.condition(p, jnp.asarray(xp), jnp.asarray(yp), jnp.asarray(mask))
        mu, var = map(np.asarray, gpm.predict(post, jnp.asarray(xs)))
        mll = float(gpm.log_marginal_likelihood(p, jnp.asarray(xp), jnp.asarray(yp), jnp.asarray(mask)))
    k = _matern52_numpy(x, x, ls, s) + (nv + gpm.JITTER) * np.eye(len(x))
    ks = _matern52_numpy(xs, x, ls, s)
    np.testing.assert_allclose(mu, mean + ks @ np.linalg.solve(k, y - mean), rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(var, s - np.sum(ks * np.linalg.solve(k, ks.T).T, axis=1), rtol=1e-7, atol=1e-10)
    assert mll == pytest.approx(multivariate_normal(np.full(len(x), mean), k).logpdf(y), rel=1e-10)


def test_likelihood_gradient_matches_finite_differences(data):
    x, y = data
    mask = np.ones(len(x), bool)
    with jax.enable_x64(True):
        p = gpm.params_from_values([0.3, 0.6, 0.9], 1.3, 1e-2, 0.1)
        flat, unravel = jax.flatten_util.ravel_pytree(p)
        f = jax.jit(lambda v: gpm.log_marginal_likelihood(unravel(v), x, y, mask))
        grad = np.asarray(jax.grad(f)(flat))
        eps = 1e-6
        fd = np.array([(f(flat + eps * e) - f(flat - eps * e)) / (2 * eps) for e in np.eye(len(flat))])
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-6)


def test_fit_recovers_lengthscale_of_data_drawn_from_the_prior():
    rng = np.random.default_rng(3)
    true_ls, n = np.array([0.15, 0.6]), 160
    x = rng.random((n, 2))
    k = _matern52_numpy(x, x, true_ls, 1.0) + 1e-4 * np.eye(n)
    y = np.linalg.cholesky(k) @ rng.standard_normal(n)
    y = (y - y.mean()) / y.std()
    with jax.enable_x64(True):
        p = jax.jit(lambda k: gpm.fit(x, y, np.ones(n, bool), k, n_starts=1, n_steps=40))(jax.random.PRNGKey(0))
        got = np.asarray(gpm.lengthscales(p))
    np.testing.assert_allclose(got, true_ls, rtol=0.3)
    assert got[0] < got[1]


@pytest.mark.parametrize("prior", ["lognormal", "dim_scaled"])
def test_a_fit_stopped_at_a_small_gradient_ends_where_every_step_ends_and_a_large_tolerance_stops_early(data, prior):
    # The reference: every start run for 200 steps, far past convergence. A start stopped once its
    # gradient is below 1e-6 reaches the same loss; one stopped at a tolerance of 1 (the largest
    # allowed) stops after its first step, well short of it, so the tolerance decides the steps.
    x, y = data
    mask = np.ones(len(y), bool)
    with jax.enable_x64(True):
        def fitted_loss(**kw):
            p = jax.jit(lambda k: gpm.fit(x, y, mask, k, n_starts=2, prior=prior, **kw))(jax.random.PRNGKey(1))
            if prior == "dim_scaled":
                p = p._replace(raw_outputscale=gpm.default_params(x.shape[1]).raw_outputscale)
            return float(gpm.fit_loss(p, jnp.asarray(x), jnp.asarray(y), jnp.asarray(mask), prior))

        full = fitted_loss(n_steps=200)
        stopped = fitted_loss(n_steps=200, gradient_tolerance=1e-6)
        early = fitted_loss(n_steps=200, gradient_tolerance=1.0)
    assert abs(stopped - full) < 1e-9
    assert early > full + 1e-3


def test_the_dim_scaled_prior_is_botorchs_and_its_fit_holds_the_outputscale_at_one(data):
    """prior="dim_scaled": the log-prior is scipy's LogNormal densities of the lengthscales
    (Hvarfner et al.'s loc sqrt(2) + log(d) / 2, scale sqrt(3)) and of the noise variance
    (loc -4, scale 1), with no outputscale term; the fit leaves the outputscale at 1 and is,
    among fits with the outputscale at 1, no worse than a nearby point."""
    from scipy.stats import lognorm

    x, y = data
    ls, nv = np.array([0.2, 0.7, 1.5]), 0.03
    with jax.enable_x64(True):
        for os_ in (1.0, 5.0):  # the outputscale plays no part in the prior
            got = float(gpm.log_prior(gpm.params_from_values(ls, os_, nv), "dim_scaled"))
            lengthscales = lognorm.logpdf(ls, np.sqrt(3.0), scale=np.exp(np.sqrt(2.0) + 0.5 * np.log(3)))
            np.testing.assert_allclose(got, lengthscales.sum() + lognorm.logpdf(nv, 1.0, scale=np.exp(-4.0)), rtol=1e-10)
        mask = np.ones(len(y), bool)
        p = gpm.fit(jnp.asarray(x), jnp.asarray(y), jnp.asarray(mask), jax.random.PRNGKey(0), n_starts=2, n_steps=60,
                    prior="dim_scaled")
        assert float(gpm.outputscale(p)) == pytest.approx(1.0, abs=1e-12)
        loss = lambda q: float(gpm.fit_loss(q, x, y, mask, "dim_scaled"))  # noqa: E731
        for moved in (p._replace(raw_noise=p.raw_noise + 0.05), p._replace(raw_lengthscales=p.raw_lengthscales - 0.05)):
            assert loss(p) <= loss(moved) + 1e-9


def test_the_small_noise_prior_is_the_lognormal_prior_with_botorchs_noise_prior():
    """prior="small_noise": scipy's LogNormal densities of the lengthscales (as "lognormal")
    and of the noise variance (loc -4, scale 1, BoTorch's since 0.12), and the Gamma(2, 0.15)
    of the outputscale, which it fits."""
    from scipy.stats import gamma, lognorm

    ls, nv = np.array([0.2, 0.7, 1.5]), 0.03
    lengthscales = lognorm.logpdf(ls, np.sqrt(3.0), scale=np.exp(np.sqrt(2.0) + 0.5 * np.log(3))).sum()
    with jax.enable_x64(True):
        for os_ in (0.5, 5.0):
            got = float(gpm.log_prior(gpm.params_from_values(ls, os_, nv), "small_noise"))
            want = lengthscales + gamma.logpdf(os_, 2.0, scale=1 / 0.15) + lognorm.logpdf(nv, 1.0, scale=np.exp(-4.0))
            np.testing.assert_allclose(got, want, rtol=1e-10)


def test_the_unit_outputscale_prior_has_no_outputscale_term_and_its_fit_holds_it_at_one(data):
    """prior="unit_outputscale": the "lognormal" prior's lengthscale and noise terms (scipy's
    LogNormal and Gamma(1.1, 0.05) densities), no outputscale term; the fit leaves it at 1."""
    from scipy.stats import gamma, lognorm

    x, y = data
    ls, nv = np.array([0.2, 0.7, 1.5]), 0.03
    with jax.enable_x64(True):
        for os_ in (1.0, 5.0):
            got = float(gpm.log_prior(gpm.params_from_values(ls, os_, nv), "unit_outputscale"))
            want = (lognorm.logpdf(ls, np.sqrt(3.0), scale=np.exp(np.sqrt(2.0) + 0.5 * np.log(3))).sum()
                    + gamma.logpdf(nv, 1.1, scale=1 / 0.05))
            np.testing.assert_allclose(got, want, rtol=1e-10)
        p = gpm.fit(jnp.asarray(x), jnp.asarray(y), jnp.asarray(np.ones(len(y), bool)), jax.random.PRNGKey(0),
                    n_starts=2, n_steps=60, prior="unit_outputscale")
        assert float(gpm.outputscale(p)) == pytest.approx(1.0, abs=1e-12)


def test_every_prior_setting_is_a_prior_the_gp_knows():
    from mjxskill.gp.settings import CHOICES

    assert set(CHOICES["prior"]) == set(gpm.PRIORS)


def test_importing_and_using_the_gp_leaves_float32_default():
    from mjxskill.gp import optimizer  # noqa: F401

    assert not jax.config.jax_enable_x64
    assert jnp.zeros(2).dtype == jnp.float32


@settings(max_examples=25, deadline=None)
@given(b=st.integers(1, 5), n=st.integers(1, 9), seed=st.integers(0, 2**31 - 1))
def test_symmetric_quadratic_form_gradients_are_autodiffs_of_the_plain_form(b, n, seed):
    # The custom VJP reuses k a for the gradient in k; the reference is autodiff of the plain
    # expression, which multiplies by a^T itself (equal for symmetric a).
    with jax.enable_x64(True):
        rng = np.random.default_rng(seed)
        k = jnp.asarray(rng.standard_normal((b, n)))
        half = rng.standard_normal((n, n))
        a = jnp.asarray(half + half.T)
        g = jnp.asarray(rng.standard_normal(b))

        def plain(k, a):
            return jnp.sum((k @ a) * k, axis=-1)

        np.testing.assert_allclose(gpm.symmetric_quadratic_form(k, a), plain(k, a), rtol=1e-12, atol=1e-12)
        ours = jax.vjp(gpm.symmetric_quadratic_form, k, a)[1](g)
        reference = jax.vjp(plain, k, a)[1](g)
        for got, want in zip(ours, reference):
            np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10)
