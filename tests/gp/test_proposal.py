"""Proposal internals: the Kriging believer's Schur-complement update against refactorizing,
the deflated variance, pending points in the incumbent (at believed values, or drawn jointly
with the candidate), and the per-objective and hypervolume-scalarization paths of the optimizer."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjxskill.gp import AcquisitionSettings, MOBOConfig, ask, init, tell
from mjxskill.gp import gp as gpm
from mjxskill.gp import hypervolume_scalarization as hvs
from mjxskill.gp.element_scalarizations import element_scalarizations
from mjxskill.gp.acquisition_search import maximize, raw_candidates
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


def test_a_draw_of_the_pending_values_moves_the_mean_as_conditioning_on_them_does():
    """pending="draws": with the pending points' values drawn as mean + chol @ e, the
    candidate's mean given them is mean + w.T @ e; the reference appends the pending points
    with those values (observed with the fitted noise) and refactorizes."""
    rng = np.random.default_rng(1)
    x = rng.random((12, 2))
    y = np.sin(5 * x[:, 0]) + x[:, 1]
    y = (y - y.mean()) / y.std()
    mask = np.arange(12) < 9
    fantasies = rng.random((3, 2))
    fantasy_mask = np.array([True, True, False])
    xs = rng.random((5, 2))
    e = rng.standard_normal(3)
    with jax.enable_x64(True):
        p = gpm.params_from_values([0.3, 0.5], 1.2, 1e-2, 0.1)
        post = gpm.condition(p, jnp.asarray(x), jnp.asarray(y), jnp.asarray(mask))
        predict, chol = _believer_predictor(post, jnp.asarray(fantasies), jnp.asarray(fantasy_mask), weights=True)
        mean, var, w = predict(jnp.asarray(xs))
        believed, _ = gpm.predict(post, jnp.asarray(fantasies[:2]))
        drawn = np.asarray(believed) + (np.asarray(chol) @ e)[:2]
        # the same noise on the appended rows as on the data: the GP's own conditioning
        x2 = np.concatenate([x[mask], fantasies[:2]])
        ref = gpm.condition(p, jnp.asarray(x2), jnp.asarray(np.concatenate([y[mask], drawn])), jnp.ones(len(x2), bool))
        ref_mean, ref_var = gpm.predict(ref, jnp.asarray(xs))
    np.testing.assert_allclose(np.asarray(mean) + np.asarray(w).T @ e, ref_mean, atol=1e-8)
    np.testing.assert_allclose(var, ref_var, rtol=1e-6, atol=1e-10)
    assert np.all(np.asarray(w)[2] == 0.0)  # the element not chosen yet moves nothing


def test_per_objective_model_with_moment_matching_proposes_distinct_points_in_bounds():
    cfg = MOBOConfig(bounds=[[0.0, 0.0], [1.0, 1.0]], n_objectives=2, batch_size=3, n_init=6, seed=1,
                     acquisition=AcquisitionSettings(bucket=16, n_raw=64, n_restarts=2, n_opt_steps=5, fit_starts=1,
                                                     fit_steps=5, model="per_objective", ei="moments",
                                                     scalarization="chebyshev"))
    x = np.random.default_rng(0).random((6, 2))
    state = tell(init(cfg), x, np.stack([x[:, 0], 1 - x[:, 0] + x[:, 1] ** 2], 1))
    batch = ask(state)
    assert batch.shape == (3, 2) and np.all((batch >= 0) & (batch <= 1))
    assert np.min(np.linalg.norm(batch[:, None] - batch[None], axis=-1) + np.eye(3) * 9) > 1e-3


def _two_objective_posteriors(rng, n=10):
    x = rng.random((n, 2))
    y = np.stack([x[:, 0], 1 - x[:, 0] + x[:, 1] ** 2], 1)
    mask = np.ones(n, bool)
    posts = []
    for i in range(2):
        p = gpm.params_from_values([0.4, 0.6], 1.0, 1e-4)
        posts.append(gpm.condition(p, jnp.asarray(x), jnp.asarray((y[:, i] - y[:, i].mean()) / y[:, i].std()),
                                   jnp.asarray(mask)))
    return x, y, mask, posts


def test_deflated_variance_vanishes_at_observed_points_and_keeps_the_latent_one_away():
    rng = np.random.default_rng(3)
    with jax.enable_x64(True):
        x, _, _, posts = _two_objective_posteriors(rng)
        none = (jnp.zeros((2, 2)), jnp.zeros(2, bool))
        far = jnp.asarray(rng.random((4, 2)))
        _, latent_at = _believer_predictor(posts[0], *none)(jnp.asarray(x[:3]))
        _, deflated_at = _believer_predictor(posts[0], *none, deflate=True)(jnp.asarray(x[:3]))
        _, latent_far = _believer_predictor(posts[0], *none)(far)
        _, deflated_far = _believer_predictor(posts[0], *none, deflate=True)(far)
        nv = float(gpm.noise(posts[0].params))
    assert np.all(np.asarray(latent_at) > 0.5 * nv)  # ~ the noise variance at a noiseless observation
    # Exactly 0 in exact arithmetic (the latent variance at a training point is at most the
    # noise variance); the explicit inverse leaves ~1e-6 relative error on the 1 - 1e-4 it subtracts.
    assert np.all(np.asarray(deflated_at) < 0.05 * nv)
    np.testing.assert_allclose(deflated_far, np.maximum(np.asarray(latent_far) - nv, 1e-12), rtol=1e-9)


@pytest.mark.parametrize("scalarization, improvement", [("chebyshev", "directions"), ("hypervolume", "directions"),
                                                        ("hypervolume", "exact")])
def test_pending_values_take_away_the_improvement_a_pending_point_already_offers(scalarization, improvement):
    rng = np.random.default_rng(4)
    y_norm = rng.random((12, 2))
    mask = np.ones(12, bool)
    better = np.array([[0.01, 0.02]])  # improves on every observation in every direction
    with jax.enable_x64(True):
        args = (jnp.asarray(y_norm), jnp.asarray(mask), jnp.array([1.1, 1.1]), jax.random.PRNGKey(0), 2)
        var = jnp.full((1, 2), 1e-10)  # (nearly) certain: EI is the improvement itself
        pend, pend_mask = jnp.asarray(better), jnp.array([True])
        got = {}
        drawn = (scalarization, improvement) == ("hypervolume", "directions")  # where pending="draws" applies
        for pending in ("variance", "values") + ("draws",) * drawn:
            settings = AcquisitionSettings(scalarization=scalarization, pending=pending, tau=1e-6,
                                           hypervolume_improvement=improvement)
            scal = element_scalarizations(*args, settings)
            best = jax.tree.map(lambda a: a[0], scal.incumbents(scal.space, jnp.asarray(mask)))
            # drawn: every one of the n_draws joint draws puts the pending point at the same value
            given = jnp.broadcast_to(pend, (settings.n_draws,) + pend.shape) if pending == "draws" else pend
            got[pending] = float(scal.log_ei(0, best, given, pend_mask)(jnp.asarray(better), var)[0])
    assert got["variance"] > np.log(1e-3)  # a real improvement while the pending point is ignored
    assert got["values"] < np.log(1e-5)  # none left once the pending point counts at its believed value
    assert not drawn or got["draws"] < np.log(1e-5)  # nor where it counts at drawn values that improve


@pytest.mark.parametrize("draw_pairing, improvement, pending", [("shared", "directions", "values"),
                                                                ("per_direction", "directions", "values"),
                                                                ("per_direction", "exact", "values"),
                                                                ("shared", "directions", "draws")])
def test_hypervolume_scalarization_proposes_distinct_points_in_bounds(draw_pairing, improvement, pending):
    cfg = MOBOConfig(bounds=[[0.0, 0.0], [1.0, 1.0]], n_objectives=2, batch_size=3, n_init=6, seed=1,
                     acquisition=AcquisitionSettings(bucket=16, n_raw=64, n_restarts=2, n_opt_steps=5, fit_starts=1,
                                                     fit_steps=5, scalarization="hypervolume", model="per_objective",
                                                     n_directions=2, pending=pending, variance="deflated",
                                                     directions="quasi_random", single_direction_share=0.34,
                                                     single_direction_reference="front", incumbent="posterior_mean",
                                                     draw_pairing=draw_pairing, hypervolume_improvement=improvement),
                     ref_point=(1.2, 2.2))
    x = np.random.default_rng(0).random((6, 2))
    state = tell(init(cfg), x, np.stack([x[:, 0], 1 - x[:, 0] + x[:, 1] ** 2], 1))
    batch = ask(state)
    assert batch.shape == (3, 2) and np.all((batch >= 0) & (batch <= 1))
    assert np.min(np.linalg.norm(batch[:, None] - batch[None], axis=-1) + np.eye(3) * 9) > 1e-3


def _anchored_value(v, lam):
    """Golovin and Zhang's scalarization in reference units, from its definition (numpy):
    t = min_i (1 - v_i) / lam_i, t^m where positive, t itself below."""
    t = np.min((1.0 - v) / lam, axis=-1)
    return np.where(t > 0, np.maximum(t, 0.0) ** v.shape[-1], t)


def test_single_direction_elements_scalarize_about_the_fronts_own_reference():
    rng = np.random.default_rng(7)
    y_norm = rng.random((15, 2)) ** 2
    mask = np.arange(15) < 12  # 3 padding rows
    settings = AcquisitionSettings(scalarization="hypervolume", model="per_objective", n_directions=8,
                                   directions="quasi_random", single_direction_share=0.5,
                                   single_direction_reference="front", beyond_reference="linear")
    with jax.enable_x64(True):
        scal = element_scalarizations(jnp.asarray(y_norm), jnp.asarray(mask), jnp.array([1.5, 1.5]), jax.random.PRNGKey(1), 4,
                              settings)
        best = np.asarray(scal.incumbents(scal.space, jnp.asarray(mask)))  # (4, 8)
    u, lam, scale = np.asarray(scal.space), np.asarray(scal.directions), np.asarray(scal.scale)
    front_ref = np.minimum(hvs.reference_point(u[mask], settings.ref_margin), 1.0)
    assert np.all(front_ref < 0.9)  # the front's reference lies well inside the run's here
    # The first two elements average 8 distinct directions about the run's reference (1).
    np.testing.assert_allclose(scale[:2], 1.0)
    assert len(np.unique(np.round(lam[0, :, 0], 12))) == 8
    np.testing.assert_allclose(best[:2], np.max(_anchored_value(u[mask][None, None] / 1.0, lam[:2, :, None]), axis=-1))
    # The last two follow one direction each, about the front's own reference point.
    np.testing.assert_allclose(scale[2:], np.broadcast_to(front_ref, (2, 2)), rtol=1e-9)
    np.testing.assert_allclose(lam[2:], np.broadcast_to(lam[2:, :1], lam[2:].shape))
    np.testing.assert_allclose(best[2:], np.max(_anchored_value(u[mask][None, None] / front_ref, lam[2:, :, None]),
                                                axis=-1), rtol=1e-9)
    np.testing.assert_allclose(np.asarray(scal.targets)[2:, mask], -np.min((1.0 - u[mask] / front_ref) / lam[2:, :1], axis=-1),
                               rtol=1e-9)


@pytest.mark.parametrize("scalarization", ["chebyshev", "hypervolume"])
def test_posterior_mean_incumbent_follows_the_model_not_a_noisy_observation(scalarization):
    """The incumbent from the model's means at the observed points: where the GP interpolates
    (tiny noise) it is the observed incumbent; where it smooths (noise fitted), one observation
    far below the others' trend no longer sets it, so re-evaluating that point offers no
    improvement the model believes in."""
    rng = np.random.default_rng(5)
    x = rng.random((14, 2))
    y = np.stack([x[:, 0], 1 - x[:, 0] + 0.3 * x[:, 1]], 1)
    y_low = y.copy()
    y_low[3] -= 0.4  # an outlier below the trend in both objectives
    mask = np.ones(14, bool)
    settings = AcquisitionSettings(scalarization=scalarization, model="per_objective", n_directions=4,
                                   beyond_reference="linear")

    def incumbents(values, noise):
        fitted = []
        for i in range(2):
            col = values[:, i]
            post = gpm.condition(gpm.params_from_values([0.5, 0.5], 1.0, noise), jnp.asarray(x),
                                 jnp.asarray((col - col.mean()) / col.std()), jnp.asarray(mask))
            fitted.append(np.asarray(gpm.predict(post, jnp.asarray(x))[0]) * col.std() + col.mean())
        scal = element_scalarizations(jnp.asarray(values), jnp.asarray(mask), jnp.array([1.5, 1.5]), jax.random.PRNGKey(0), 3,
                              settings)
        # The fitted means in the scalarization's space (hypervolume: reference units, an
        # affine map of each objective; its scale read off two rows).
        scale = (np.asarray(scal.space)[1] - np.asarray(scal.space)[0]) / (values[1] - values[0])
        in_space = np.asarray(scal.space) + (np.stack(fitted, 1) - values) * scale
        return (np.asarray(scal.incumbents(scal.space, jnp.asarray(mask))),
                np.asarray(scal.incumbents(jnp.asarray(in_space), jnp.asarray(mask))))

    with jax.enable_x64(True):
        observed, believed = incumbents(y, 1e-6)
        np.testing.assert_allclose(believed, observed, rtol=1e-3, atol=1e-4)
        observed, believed = incumbents(y_low, 0.3)
    better = np.less if scalarization == "chebyshev" else np.greater  # Chebyshev is minimized
    assert np.all(better(observed, believed))  # the outlier no longer sets the bar


@jax.enable_x64(True)
def test_raw_candidates_on_the_bounds_put_half_their_coordinates_there_and_none_outside():
    key = jax.random.PRNGKey(3)
    plain = AcquisitionSettings(n_raw=4000)
    # share 0: the uniform draw of the same key, unchanged (runs before the setting existed)
    np.testing.assert_array_equal(raw_candidates(key, 5, plain), jax.random.uniform(key, (4000, 5), jnp.float64))
    raw = np.asarray(raw_candidates(key, 5, AcquisitionSettings(n_raw=4000, raw_bounds_share=0.25)))
    assert raw.shape == (4000, 5) and raw.min() >= 0.0 and raw.max() <= 1.0
    on = (raw == 0.0) | (raw == 1.0)
    assert not on[:3000].any()  # the uniform ones
    # each coordinate of the other 1000 on a bound with probability 1/2, either bound alike
    assert on[3000:].mean() == pytest.approx(0.5, abs=0.02)
    assert (raw[3000:] == 0.0).mean() == pytest.approx(0.25, abs=0.02)


@jax.enable_x64(True)
def test_candidates_on_the_bounds_find_an_improvement_confined_to_a_corner():
    """An acquisition flat (no gradient) but for a ball of radius 0.1 about a corner of the cube,
    as where a front lies on the cube's faces: uniform candidates rarely land in it, those on the
    bounds often do, and Adam then climbs to the corner."""
    corner = jnp.array([1.0, 0.0, 1.0])
    acq = lambda xs: jnp.where(jnp.linalg.norm(xs - corner, axis=-1) < 0.1,  # noqa: E731
                               -jnp.linalg.norm(xs - corner, axis=-1), -1.0)
    found = {}
    for share in (0.0, 0.5):
        settings = AcquisitionSettings(n_raw=256, n_restarts=4, n_opt_steps=50, raw_bounds_share=share)
        best = [maximize(acq, jax.random.PRNGKey(k), 3, settings) for k in range(20)]
        found[share] = sum(float(jnp.linalg.norm(b - corner)) < 1e-2 for b in best)
    # uniform: 256 x 5.2e-4 = 0.13 hits expected per key; on the bounds: 128 x 1/64 = 2 at the corner
    assert found[0.5] >= 17 and found[0.0] <= 5, found
