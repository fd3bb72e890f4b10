"""The parameter prior of the optimizer (gp/prior.py), against independent references: the
density against scipy.stats.truncnorm, piBO's decaying weight in closed form, the warm-up's
draws against the mixture's CDF (KS test), the state file round trip, and, without a prior,
exactly the proposals the optimizer made before priors existed."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import json

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from mjxskill.gp import MOBOConfig, Prior, acquisition_settings, ask, init, load_state, minimize, save_state, tell
from mjxskill.gp import optimizer as opt_mod
from mjxskill.gp.prior import pibo_weight, prior_rows, unit_prior
from mjxskill.gp.prior_density import log_density
from mjxskill.gp.proposal import prior_weighted, propose_batch
from mjxskill.gp.settings import acquisition_defaults

BOUNDS = [[-1.0, 0.0], [1.0, 2.0]]
CHEAP = dict(bucket=16, n_raw=64, n_restarts=2, n_opt_steps=5, fit_starts=1, fit_steps=5, fit_max_rows=8,
             per_element_fit_max_rows=16)
MIXTURE = Prior(mean=[[-0.5, 1.5], [0.8, 0.1]], std=[[0.2, 0.3], [0.5, 0.05]], weights=[0.3, 0.7])


def objectives(x):
    return np.stack([(x[:, 0] + 0.5) ** 2 + (x[:, 1] - 1) ** 2, (x[:, 0] - 0.5) ** 2 + (x[:, 1] - 1) ** 2], 1)


def config(prior=None, n_init=5, seed=11, **acq):
    return MOBOConfig(bounds=BOUNDS, n_objectives=2, batch_size=3, n_init=n_init, seed=seed,
                      acquisition=acquisition_settings({**CHEAP, **acq}), prior=prior)


def run(state, n_batches):
    for _ in range(n_batches):
        x = ask(state)
        state = tell(state, x, objectives(x))
    return state


def truncnorm_mixture_pdf(prior: Prior, x):
    """sum_k w_k prod_i truncnorm(x_i; mean_ki, std_ki, bounds_i), by scipy."""
    lo, hi = np.asarray(BOUNDS)
    total = np.zeros(len(x))
    for w, mu, sd in zip(prior.weights, np.asarray(prior.mean), np.asarray(prior.std)):
        pdf = stats.truncnorm.pdf(x, (lo - mu) / sd, (hi - mu) / sd, loc=mu, scale=sd)
        total += w * np.prod(pdf, axis=1)
    return total


def test_log_density_is_scipy_truncnorm_mixture():
    rng = np.random.default_rng(0)
    lo, hi = np.asarray(BOUNDS)
    x = lo + rng.random((50, 2)) * (hi - lo)
    x[0] = [1.0, 2.0]  # on the bounds too
    np.testing.assert_allclose(log_density(MIXTURE, BOUNDS, x), np.log(truncnorm_mixture_pdf(MIXTURE, x)), rtol=1e-10)
    one = Prior(mean=[0.9, 0.2], std=[1e-3, 10.0])  # a sharp and an almost flat dimension
    near = np.array([[0.9005, 1.0], [0.899, 1.9]])
    np.testing.assert_allclose(log_density(one, BOUNDS, near), np.log(truncnorm_mixture_pdf(one, near)), rtol=1e-10)


@jax.enable_x64(True)
def test_pibo_shift_is_beta_over_n_times_log_prior():
    up = jax.tree.map(jnp.asarray, unit_prior(MIXTURE, BOUNDS))
    u = np.random.default_rng(1).random((20, 2))
    lo, hi = np.asarray(BOUNDS)
    # The unit cube's density is the parameter units' times the box volume (a constant).
    log_prior = np.log(truncnorm_mixture_pdf(MIXTURE, lo + u * (hi - lo))) + np.sum(np.log(hi - lo))
    acq = lambda v: -jnp.sum((v - 0.3) ** 2, axis=1)  # noqa: E731
    for beta, n in [(10.0, 10), (10.0, 40), (2.5, 7)]:
        w = pibo_weight(beta, n)
        assert w == beta / n
        shift = prior_weighted(acq, up, w, 1.0)(jnp.asarray(u)) - acq(jnp.asarray(u))
        np.testing.assert_allclose(shift, beta / n * log_prior, rtol=1e-9)
        # the belief with a uniform share: the unit cube's uniform density is 1
        for share in (0.5, 0.1):
            shift = prior_weighted(acq, up, w, share)(jnp.asarray(u)) - acq(jnp.asarray(u))
            np.testing.assert_allclose(shift, beta / n * np.log(share * np.exp(log_prior) + 1 - share), rtol=1e-9)
            assert np.all(shift >= beta / n * np.log(1 - share) - 1e-12)  # a wrong prior's pull is bounded
    assert prior_weighted(acq, None, 1.0, 0.5) is acq


def test_ask_passes_beta_over_the_number_of_observations(monkeypatch):
    seen = []

    def spy(x, y, mask, key, ref, prior=None, prior_weight=0.0, **kw):
        seen.append((int(np.sum(mask)), float(prior_weight)))
        return propose_batch(x, y, mask, key, ref, prior, prior_weight, **kw)

    monkeypatch.setattr(opt_mod, "propose_batch", spy)
    run(init(config(MIXTURE, pibo_beta=4.0)), 4)
    assert seen == [(5, 4.0 / 5), (8, 4.0 / 8)]


@pytest.mark.parametrize("fraction", [0.5, 1.0])
def test_warm_up_draws_follow_the_prior_mixed_with_uniform(fraction):
    n_init = 2000
    x = ask(init(config(MIXTURE, n_init=n_init, prior_share=fraction)), num=n_init)
    lo, hi = np.asarray(BOUNDS)
    assert x.shape == (n_init, 2) and np.all(x >= lo) and np.all(x <= hi)
    assert prior_rows(0, n_init, fraction).sum() == int(np.ceil(fraction * n_init))
    mean, std = np.asarray(MIXTURE.mean), np.asarray(MIXTURE.std)
    for i in range(2):
        def cdf(v, i=i):
            parts = [w * stats.truncnorm.cdf(v, (lo[i] - m) / s, (hi[i] - m) / s, loc=m, scale=s)
                     for w, m, s in zip(MIXTURE.weights, mean[:, i], std[:, i])]
            return fraction * np.sum(parts, axis=0) + (1 - fraction) * (v - lo[i]) / (hi[i] - lo[i])

        assert stats.kstest(x[:, i], cdf).pvalue > 0.01
        assert stats.kstest(x[:, i], stats.uniform(lo[i], hi[i] - lo[i]).cdf).pvalue < 1e-6  # the test can tell


def test_uniform_warm_up_points_stay_those_of_a_run_without_prior():
    plain, with_prior = ask(init(config(n_init=8)), 8), ask(init(config(MIXTURE, n_init=8)), 8)
    rows = prior_rows(0, 8, 0.5)
    np.testing.assert_array_equal(with_prior[~rows], plain[~rows])
    assert not np.allclose(with_prior[rows], plain[rows])


# What main (96ae370, before priors) proposed on this problem: seed 11, 5 warm-up points, 4 batches.
MAIN_PROPOSALS = np.array([
    [-0.7428595944616008, 0.9985557248802299], [0.20299671524671492, 0.05737801674388909],
    [-0.7041478308450881, 1.856422045920739], [0.9290740997692841, 1.6979785204101097],
    [-0.9970554155098676, 0.9536675176076344], [-0.49864876463621377, 0.8528248291278463],
    [-0.5728257541225803, 1.1300808138872362], [-0.5437070064219962, 0.9280301356973301],
    [-0.31849844473916644, 1.0006428830751433], [-0.15645351052615086, 0.85385854673994],
    [-0.7290936981173743, 0.005861974418100086]])


def test_without_prior_the_proposals_are_mains():
    # With generation 1's acquisition defaults (the prior's code path was written on them): the
    # comparison is of the prior's code path, so it keeps main's settings.
    cfg = MOBOConfig(bounds=BOUNDS, n_objectives=2, batch_size=3, n_init=5, seed=11,
                     acquisition=acquisition_settings(CHEAP, acquisition_defaults(1)))
    state = run(init(cfg), 4)
    np.testing.assert_allclose(state.x, MAIN_PROPOSALS, rtol=1e-9, atol=1e-12)


def test_a_strong_prior_pulls_the_proposals_toward_it():
    target = Prior(mean=[0.6, 1.6], std=[0.05, 0.05])
    state = run(init(config(target, pibo_beta=500.0, prior_share=0.9)), 3)
    model = state.x[5:]
    assert np.all(np.abs(model - [0.6, 1.6]).max(axis=1) < 0.3), model


def test_a_changed_prior_of_the_same_size_does_not_retrace(monkeypatch):
    counted = jax.jit(chex.assert_max_traces(propose_batch.__wrapped__, n=1), static_argnames=("q", "settings"))
    monkeypatch.setattr(opt_mod, "propose_batch", counted)
    state = run(init(config(MIXTURE)), 2)
    for mean in ([0.0, 1.0], [0.5, 0.5]):
        other = state._replace(config=config(Prior(mean=[mean, [0.8, 0.1]], std=MIXTURE.std)))
        ask(other)
    chex.clear_trace_counter()


def test_prior_round_trips_through_the_state_file_and_old_files_load(tmp_path):
    state = run(init(config(MIXTURE)), 3)
    path = tmp_path / "state.npz"
    save_state(state, path)
    restored = load_state(path)
    assert restored.config == state.config and restored.config.prior == MIXTURE
    np.testing.assert_array_equal(ask(restored), ask(state))
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["config_json"]))
    old = {**meta, "config": {k: v for k, v in meta["config"].items() if k != "prior"}}  # written before priors
    np.savez(path, x=state.x, y=state.y, config_json=np.array(json.dumps(old)))
    assert load_state(path).config.prior is None
    bad = {**meta, "config": {**meta["config"], "prior": {**MIXTURE.to_dict(), "std": [[0.2, -1.0], [0.5, 0.05]]}}}
    np.savez(path, x=state.x, y=state.y, config_json=np.array(json.dumps(bad)))
    with pytest.raises(ValueError, match=r"state.npz: MOBOConfig.prior: Prior.std: component 0, dimension 1 must be > 0"):
        load_state(path)


@pytest.mark.parametrize("kwargs, message", [
    (dict(mean=[2.0, 1.0], std=[0.1, 0.1]), r"Prior.mean: component 0, dimension 0 = 2 lies outside the bounds \[-1, 1\]"),
    (dict(mean=[0.0, 1.0], std=[0.1, 0.0]), r"Prior.std: component 0, dimension 1 must be > 0 and finite, got 0.0"),
    (dict(mean=[0.0, 1.0], std=[np.inf, 0.1]), r"Prior.std: component 0, dimension 0 must be > 0 and finite, got inf"),
    (dict(mean=[0.0, np.nan], std=[0.1, 0.1]), r"Prior.mean: component 0, dimension 1 is not finite"),
    (dict(mean=[0.0, 1.0, 0.0], std=[0.1, 0.1, 0.1]), r"Prior: 3 dimensions, the bounds have 2"),
    (dict(mean=[0.0, 1.0], std=[0.1, 0.1, 0.1]), r"Prior.std: shape \(1, 3\) does not match the mean's \(1, 2\)"),
    (dict(mean=[[0.0, 1.0], [0.1, 1.0]], std=[0.1, 0.1], weights=[0.5, 0.6]), r"Prior.weights: must sum to 1, got 1.1"),
    (dict(mean=[[0.0, 1.0], [0.1, 1.0]], std=[0.1, 0.1], weights=[1.5, -0.5]), r"Prior.weights: weight 1 must be > 0"),
    (dict(mean=[[0.0, 1.0], [0.1, 1.0]], std=[0.1, 0.1], weights=[1.0]), r"Prior.weights: expected 2 weights"),
])
def test_bad_priors_raise_errors_naming_the_value(kwargs, message):
    with pytest.raises(ValueError, match=message):
        MOBOConfig(bounds=BOUNDS, n_objectives=2, prior=kwargs)


def test_minimize_takes_a_prior():
    res = minimize(objectives, BOUNDS, budget=8, batch_size=3, n_init=5, seed=2, prior=Prior(mean=[0.0, 1.0], std=0.2),
                   **CHEAP)
    assert res.state.config.prior == Prior(mean=[0.0, 1.0], std=[0.2, 0.2])
    assert len(res.x) == 8
