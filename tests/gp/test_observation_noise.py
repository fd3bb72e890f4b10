"""Known per-row observation noise: the GP against dense numpy closed forms, the proposal's
noise arguments, and the optimizer state that carries noise through ask/tell/save/load."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import jax
import jax.flatten_util
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from mjxskill.gp import AcquisitionSettings, MOBOConfig, acquisition_settings, ask, init, load_state, observed
from mjxskill.gp import save_state, tell
from mjxskill.gp import element_scalarizations as es
from mjxskill.gp import gp as gpm
from mjxskill.gp import optimizer as opt_mod
from mjxskill.gp.proposal import propose_batch

LS, OS, NV, MEAN = np.array([0.3, 0.6, 0.9]), 1.3, 1e-3, 0.1
CHEAP = dict(bucket=16, n_raw=64, n_restarts=2, n_opt_steps=5, fit_starts=1, fit_steps=5)


def _matern52_numpy(a, b, ls, s):
    r = np.sqrt(np.sum(((a[:, None, :] - b[None, :, :]) / ls) ** 2, axis=-1))
    return s * (1 + np.sqrt(5) * r + 5 * r**2 / 3) * np.exp(-np.sqrt(5) * r)


def _closed_form(x, y, noise_diag, xs, ls=LS, s=OS, mean=MEAN):
    """Posterior mean and latent variance at xs, and the log marginal likelihood, in numpy."""
    k = _matern52_numpy(x, x, ls, s) + np.diag(noise_diag)
    ks = _matern52_numpy(xs, x, ls, s)
    mu = mean + ks @ np.linalg.solve(k, y - mean)
    var = s - np.sum(ks * np.linalg.solve(k, ks.T).T, axis=1)
    return mu, var, multivariate_normal(np.full(len(x), mean), k).logpdf(y)


@pytest.fixture(scope="module")
def data():
    """24 real rows with noise variances spread over seven decades, then 8 padding rows."""
    rng = np.random.default_rng(0)
    x = rng.random((24, 3))
    y = np.sin(4 * x[:, 0]) + x[:, 1] ** 2 - x[:, 2]
    y = (y - y.mean()) / y.std()
    obs = 10.0 ** rng.uniform(-6, 1, 24)
    xp = np.concatenate([x, np.full((8, 3), 123.0)])
    yp = np.concatenate([y, np.full(8, -1e3)])
    obs_p = np.concatenate([obs, [np.nan, -1.0, np.inf, 5.0, 0.0, 1e9, 1.0, 2.0]])  # padding: ignored
    mask = np.arange(32) < 24
    return x, y, obs, xp, yp, obs_p, mask, rng.random((7, 3))


def _posterior(xp, yp, mask, obs, xs, p=None):
    p = gpm.params_from_values(LS, OS, NV, MEAN) if p is None else p
    obs = None if obs is None else jnp.asarray(obs)
    post = gpm.condition(p, jnp.asarray(xp), jnp.asarray(yp), jnp.asarray(mask), obs)
    return tuple(map(np.asarray, gpm.predict(post, jnp.asarray(xs))))


def test_posterior_and_likelihood_match_the_closed_form_with_per_row_noise(data):
    x, y, obs, xp, yp, obs_p, mask, xs = data
    with jax.enable_x64(True):
        mu, var = _posterior(xp, yp, mask, obs_p, xs)
        p = gpm.params_from_values(LS, OS, NV, MEAN)
        args = (jnp.asarray(xp), jnp.asarray(yp), jnp.asarray(mask))
        mll = float(gpm.log_marginal_likelihood(p, *args, jnp.asarray(obs_p)))
    want_mu, want_var, want_mll = _closed_form(x, y, NV + gpm.JITTER + obs, xs)
    np.testing.assert_allclose(mu, want_mu, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(var, want_var, rtol=1e-7, atol=1e-10)
    assert mll == pytest.approx(want_mll, rel=1e-10)
    # The noise changes the answer: without it the posterior is another one.
    homoscedastic, _, _ = _closed_form(x, y, np.full(24, NV + gpm.JITTER), xs)
    assert np.max(np.abs(mu - homoscedastic)) > 1e-2


def test_likelihood_gradient_matches_finite_differences_with_per_row_noise(data):
    _, _, _, xp, yp, obs_p, mask, _ = data
    with jax.enable_x64(True):
        p = gpm.params_from_values(LS, OS, 1e-2, MEAN)
        flat, unravel = jax.flatten_util.ravel_pytree(p)
        args = (jnp.asarray(xp), jnp.asarray(yp), jnp.asarray(mask))
        f = jax.jit(lambda v, obs: gpm.log_marginal_likelihood(unravel(v), *args, obs))
        obs = jnp.asarray(obs_p)
        grad = np.asarray(jax.grad(f)(flat, obs))
        eps = 1e-6
        fd = np.array([(f(flat.at[i].add(eps), obs) - f(flat.at[i].add(-eps), obs)) / (2 * eps)
                       for i in range(flat.size)])
        np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-6)
        # obs_noise is data, but the surrogate's gradient in it is the true one too (real rows).
        g_obs = np.asarray(jax.grad(f, argnums=1)(flat, obs))
        for i in (0, 5, 17):
            h = 1e-6 * max(float(obs[i]), 1e-3)
            fd_i = (f(flat, obs.at[i].add(h)) - f(flat, obs.at[i].add(-h))) / (2 * h)
            assert g_obs[i] == pytest.approx(float(fd_i), rel=1e-4, abs=1e-7)


def test_fit_loss_and_fit_take_the_noise_into_account(data):
    _, _, _, xp, yp, obs_p, mask, _ = data
    with jax.enable_x64(True):
        args = (jnp.asarray(xp), jnp.asarray(yp), jnp.asarray(mask))
        p = gpm.params_from_values(LS, OS, NV, MEAN)
        with_noise = float(gpm.fit_loss(p, *args, "gamma", jnp.asarray(obs_p)))
        want = -(float(gpm.log_marginal_likelihood(p, *args, jnp.asarray(obs_p))) + float(gpm.log_prior(p))) / 24
        assert with_noise == pytest.approx(want, rel=1e-12)
        assert with_noise != pytest.approx(float(gpm.fit_loss(p, *args)), rel=1e-3)
        fitted = jax.jit(lambda k, obs: gpm.fit(*args, k, n_starts=2, n_steps=10, obs_noise=obs))(
            jax.random.PRNGKey(0), jnp.asarray(obs_p))
        assert all(np.all(np.isfinite(np.asarray(leaf))) for leaf in jax.tree.leaves(fitted))
        assert float(gpm.fit_loss(fitted, *args, "gamma", jnp.asarray(obs_p))) < with_noise


# What gp.predict returned for this data before obs_noise existed (recorded from that code).
RECORDED_MEAN = [0.4691510175679532, 0.19323371795680502, 1.1636290516841763, 0.14447705049138784, 1.4923684170635996]
RECORDED_VAR = [0.21889754766309455, 0.05262699371522017, 0.08733216953845502, 0.11692920267275952, 0.21551744566258013]
RECORDED_MLL = -11.618242531798757


def test_no_noise_is_todays_gp_and_zero_noise_the_same_posterior():
    rng = np.random.default_rng(0)
    x = rng.random((20, 3))
    y = np.sin(4 * x[:, 0]) + x[:, 1]
    y = (y - y.mean()) / y.std()
    mask = np.arange(20) < 16
    p_vals = ([0.3, 0.6, 0.9], 1.3, 1e-2, 0.1)
    xs = rng.random((5, 3))
    with jax.enable_x64(True):
        p = gpm.params_from_values(*p_vals)
        mu, var = _posterior(x, y, mask, None, xs, p)
        mll = float(gpm.log_marginal_likelihood(p, jnp.asarray(x), jnp.asarray(y), jnp.asarray(mask)))
        np.testing.assert_allclose(mu, RECORDED_MEAN, rtol=1e-12)
        np.testing.assert_allclose(var, RECORDED_VAR, rtol=1e-12)
        assert mll == pytest.approx(RECORDED_MLL, rel=1e-12)
        # The covariance without noise is today's expression, bit for bit.
        xj, mj = jnp.asarray(x), jnp.asarray(mask)
        k = jnp.where(mj[:, None] & mj[None, :], gpm.matern52(xj, xj, gpm.lengthscales(p), gpm.outputscale(p)), 0.0)
        today = k + jnp.eye(20) * jnp.where(mj, gpm.noise(p) + gpm.JITTER, 1.0)
        np.testing.assert_array_equal(np.asarray(gpm._padded_cov(p, xj, mj)), np.asarray(today))
        mu0, var0 = _posterior(x, y, mask, np.zeros(20), xs, p)
    np.testing.assert_allclose(mu0, mu, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(var0, var, rtol=1e-12, atol=1e-14)


def test_a_row_with_a_huge_noise_is_nearly_ignored(data):
    x, y, obs, _, _, _, _, xs = data
    outlier = np.array([[0.5, 0.5, 0.5]])
    x2, y2 = np.concatenate([x, outlier]), np.concatenate([y, [100.0]])
    with jax.enable_x64(True):
        without, _ = _posterior(x, y, np.ones(24, bool), obs, xs)
        ignored, _ = _posterior(x2, y2, np.ones(25, bool), np.append(obs, 1e10), xs)
        heeded, _ = _posterior(x2, y2, np.ones(25, bool), np.append(obs, 1e-4), xs)
    np.testing.assert_allclose(ignored, without, atol=1e-6)
    assert np.max(np.abs(heeded - without)) > 1.0


def test_duplicate_inputs_give_the_precision_weighted_mean():
    x0 = np.array([[0.3, 0.7]])
    x = np.repeat(x0, 3, axis=0)
    y = np.array([1.0, -0.5, 2.0])
    obs = np.array([0.01, 0.5, 4.0])
    ls, s, nv, mean = np.array([0.4, 0.4]), 2.0, 2e-6, 0.2
    with jax.enable_x64(True):
        p = gpm.params_from_values(ls, s, nv, mean)
        mu, var = _posterior(x, y, np.ones(3, bool), obs, x0, p)
    v = nv + gpm.JITTER + obs  # each row's total noise variance
    y_bar, v_bar = np.sum(y / v) / np.sum(1 / v), 1 / np.sum(1 / v)  # the precision-weighted mean
    # The rows are one observation y_bar of f(x0) with noise variance v_bar.
    assert mu[0] == pytest.approx(mean + s / (s + v_bar) * (y_bar - mean), rel=1e-9)
    assert var[0] == pytest.approx(s * v_bar / (s + v_bar), rel=1e-7)


@pytest.mark.parametrize("beyond_reference", ["log", "linear"])
def test_variance_factor_is_the_squared_slope_of_the_map_into_the_gps_space(beyond_reference):
    rng = np.random.default_rng(3)
    y = rng.random((12, 2)) * np.array([1.0, 3.0])
    mask = np.arange(12) < 10
    ref = np.array([0.6, 1.5])  # some rows lie beyond it: compressed
    settings = AcquisitionSettings(n_directions=4, beyond_reference=beyond_reference)
    with jax.enable_x64(True):
        def space(yn):
            return es.element_scalarizations(yn, jnp.asarray(mask), jnp.asarray(ref), jax.random.PRNGKey(0), 2,
                                             settings).space

        scal = es.element_scalarizations(jnp.asarray(y), jnp.asarray(mask), jnp.asarray(ref), jax.random.PRNGKey(0),
                                         2, settings)
        factor = np.asarray(scal.variance_factor)
        base = np.asarray(space(jnp.asarray(y)))
        ideal = np.argmin(np.where(mask[:, None], y, np.inf), axis=0)
        for i in range(10):
            for k in range(2):
                if i == ideal[k]:
                    continue  # moving the ideal point moves the units themselves
                h = 1e-6
                slope = (np.asarray(space(jnp.asarray(y).at[i, k].add(h)))[i, k] - base[i, k]) / h
                assert factor[i, k] == pytest.approx(slope**2, rel=1e-4)
        assert np.asarray(scal.new_variance_factor) == pytest.approx(1 / (ref - y[mask].min(axis=0)) ** 2, rel=1e-12)
        cheb = es.element_scalarizations(jnp.asarray(y), jnp.asarray(mask), jnp.asarray(ref), jax.random.PRNGKey(0), 2,
                                         AcquisitionSettings(scalarization="chebyshev"))
        assert np.all(np.asarray(cheb.variance_factor) == 1.0) and np.all(np.asarray(cheb.new_variance_factor) == 1.0)
    if beyond_reference == "log":
        assert np.any(factor < 1 / (ref - y[mask].min(axis=0)) ** 2 * (1 - 1e-3))  # some rows compressed


@pytest.mark.parametrize("m", [2, 3])
def test_propose_batch_with_noise_returns_points_in_the_unit_cube(m):
    rng = np.random.default_rng(m)
    n, d = 16, 3
    x = rng.random((n, d))
    y = rng.random((n, m))
    mask = np.arange(n) < 12
    obs = 10.0 ** rng.uniform(-5, -1, (n, m))
    obs[0, 0], obs[1, -1] = np.nan, -1.0  # a caller's bug: taken as 0
    settings = AcquisitionSettings(**CHEAP)
    with jax.enable_x64(True):
        args = (jnp.asarray(x), jnp.asarray(y), jnp.asarray(mask), jax.random.PRNGKey(1))
        pts, params = propose_batch(*args, obs_noise=jnp.asarray(obs), new_noise=jnp.full((m,), 1e-3), q=3,
                                    settings=settings)
        pts = np.asarray(pts)
        assert pts.shape == (3, d) and np.all((pts >= 0) & (pts <= 1))
        assert all(np.all(np.isfinite(np.asarray(leaf))) for leaf in jax.tree.leaves(params))
        # Zero noise is no noise.
        zero, _ = propose_batch(*args, obs_noise=jnp.zeros((n, m)), new_noise=jnp.zeros((m,)), q=3, settings=settings)
        plain, _ = propose_batch(*args, q=3, settings=settings)
        np.testing.assert_allclose(np.asarray(zero), np.asarray(plain), atol=1e-9)


@pytest.mark.parametrize("model", ["hybrid", "scalarized"])
def test_noise_with_another_model_than_per_objective_is_refused(model):
    with jax.enable_x64(True), pytest.raises(ValueError, match="per_objective"):
        propose_batch(jnp.zeros((4, 2)), jnp.zeros((4, 2)), jnp.ones(4, bool), jax.random.PRNGKey(0),
                      obs_noise=jnp.zeros((4, 2)), q=2, settings=AcquisitionSettings(model=model, **CHEAP))


def _objectives(x):
    return np.stack([(x[:, 0] + 0.5) ** 2 + (x[:, 1] - 1) ** 2, (x[:, 0] - 0.5) ** 2 + (x[:, 1] - 1) ** 2], 1)


def _config():
    return MOBOConfig([[-1.0, 0.0], [1.0, 2.0]], 2, batch_size=3, n_init=5, seed=7,
                      acquisition=acquisition_settings({**CHEAP, "fit_max_rows": 8}))


def test_ask_passes_the_noise_normalized_and_padded(monkeypatch):
    seen = []

    def spy(*args, **kw):
        seen.append(kw)
        return propose_batch(*args, **kw)

    monkeypatch.setattr(opt_mod, "propose_batch", spy)
    rng = np.random.default_rng(0)
    x = -1 + 2 * rng.random((7, 2))
    x[:, 1] += 1
    y = _objectives(x)
    y[3, 1] = np.nan  # a crashed row: its noise is not used
    noise = rng.uniform(0.01, 0.1, (7, 2))
    state = observed(_config(), x, y, noise)
    batch = ask(state)
    assert batch.shape == (3, 2)
    np.testing.assert_array_equal(batch, ask(state))  # pure
    kw = seen[0]
    span = np.nanmax(y, axis=0) - np.nanmin(y, axis=0)
    want = np.where(np.isfinite(y), noise, 0.0) / span**2
    assert kw["obs_noise"].shape == (16, 2) and np.all(kw["obs_noise"][7:] == 0)
    np.testing.assert_allclose(kw["obs_noise"][:7], want, rtol=1e-12)
    np.testing.assert_allclose(kw["new_noise"], [np.median(noise[:, 0]) / span[0] ** 2,
                                                 np.median(np.delete(noise[:, 1], 3)) / span[1] ** 2], rtol=1e-12)
    # Without noise, no noise arguments: today's call.
    ask(observed(_config(), x, y))
    assert "obs_noise" not in seen[-1] and "new_noise" not in seen[-1]


def test_ask_tell_save_load_round_trip_a_state_with_noise(tmp_path):
    state = init(_config())
    while len(state.x) < 11:
        x = ask(state)
        y = _objectives(x)
        state = tell(state, x, y, np.full_like(y, 1e-3) * (1 + np.arange(len(x)))[:, None])
    assert state.noise.shape == (11, 2)
    save_state(state, tmp_path / "s.npz")
    back = load_state(tmp_path / "s.npz")
    np.testing.assert_array_equal(back.noise, state.noise)
    np.testing.assert_array_equal(back.x, state.x)
    np.testing.assert_array_equal(ask(back), ask(state))
    rebuilt = observed(state.config, state.x, state.y, state.noise)
    np.testing.assert_array_equal(ask(rebuilt), ask(state))
    # A state without noise writes no noise array and reads back without one.
    plain = observed(state.config, state.x, state.y)
    save_state(plain, tmp_path / "p.npz")
    with np.load(tmp_path / "p.npz") as data:
        assert "noise" not in data.files
    assert load_state(tmp_path / "p.npz").noise is None


def test_tell_refuses_a_mix_of_rows_with_and_without_noise_and_bad_noise():
    x = np.array([[0.0, 1.0], [0.5, 0.5]])
    y = _objectives(x)
    with_noise = tell(init(_config()), x, y, np.ones_like(y))
    without = tell(init(_config()), x, y)
    with pytest.raises(ValueError, match="noise must be given for all rows or for none"):
        tell(with_noise, x, y)
    with pytest.raises(ValueError, match="noise must be given for all rows or for none"):
        tell(without, x, y, np.ones_like(y))
    with pytest.raises(ValueError, match="noise must have shape"):
        tell(init(_config()), x, y, np.ones(2))
    with pytest.raises(ValueError, match="noise row 1"):
        tell(init(_config()), x, y, np.array([[0.0, 1.0], [-1.0, 1.0]]))
    # A non-finite value may have any noise: it is not used.
    y_bad = y.copy()
    y_bad[1, 0] = np.inf
    assert tell(init(_config()), x, y_bad, np.array([[0.0, 1.0], [np.nan, 1.0]])).noise.shape == (2, 2)
