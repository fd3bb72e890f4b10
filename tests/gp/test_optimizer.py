"""Ask/tell optimizer: warm-up, determinism and resume, static shapes, bad input, minimize."""

import mjxskill  # noqa: F401  (XLA flags before jax runs)

import dataclasses

import chex
import jax
import numpy as np
import pytest

from mjxskill.gp import (
    AcquisitionSettings,
    MOBOConfig,
    acquisition_settings,
    ask,
    hypervolume,
    init,
    load_state,
    minimize,
    pareto_mask,
    save_state,
    tell,
)
from mjxskill.gp import optimizer as opt_mod
from mjxskill.gp.proposal import propose_batch
from mjxskill.gp.settings import acquisition_defaults

BOUNDS = [[-1.0, 0.0], [1.0, 2.0]]
# Small acquisition/fit budgets and a small bucket keep compiles and runs cheap.
# fit_max_rows and per_element_fit_max_rows are set so that both the subset fit and the
# shared and per-element fits run (buckets of 16 and 32 rows).
CHEAP = dict(bucket=16, n_raw=64, n_restarts=2, n_opt_steps=5, fit_starts=1, fit_steps=5,
             fit_max_rows=8, per_element_fit_max_rows=16)


def objectives(x):
    """Two conflicting quadratics; Pareto set on the segment between (-0.5, 1) and (0.5, 1)."""
    return np.stack([(x[:, 0] + 0.5) ** 2 + (x[:, 1] - 1) ** 2, (x[:, 0] - 0.5) ** 2 + (x[:, 1] - 1) ** 2], 1)


PROBLEM = ("bounds", "n_objectives", "batch_size", "n_init", "seed", "ref_point")


def config(**kw):
    """The test problem's config; keyword arguments that are not problem fields are acquisition settings."""
    problem = {k: v for k, v in kw.items() if k in PROBLEM}
    acq = {**CHEAP, **{k: v for k, v in kw.items() if k not in PROBLEM}}
    return MOBOConfig(**{**dict(bounds=BOUNDS, n_objectives=2, batch_size=3, n_init=5, seed=7), **problem},
                      acquisition=acquisition_settings(acq))


def run(state, n_batches):
    for _ in range(n_batches):
        x = ask(state)
        state = tell(state, x, objectives(x))
    return state


def test_warm_up_is_uniform_random_then_the_model_takes_over():
    state = init(config())
    first = ask(state)
    assert first.shape == (3, 2)
    state = tell(state, first, objectives(first))
    second = ask(state)
    assert second.shape == (2, 2)  # cut so that exactly n_init random points are drawn
    state = tell(state, second, objectives(second))
    expected = np.random.default_rng([7, 3]).random((2, 2)) * [2.0, 2.0] + [-1.0, 0.0]
    np.testing.assert_allclose(second, expected)
    model_batch = ask(state)
    assert model_batch.shape == (3, 2)
    lo, hi = np.asarray(BOUNDS)
    assert np.all(model_batch >= lo) and np.all(model_batch <= hi)
    # Kriging believer: the batch points differ from each other.
    assert np.min(np.linalg.norm(model_batch[:, None] - model_batch[None], axis=-1) + np.eye(3) * 9) > 1e-3


def test_resumed_run_proposes_exactly_what_an_uninterrupted_run_does(tmp_path):
    state = run(init(config()), 4)
    path = tmp_path / "state.npz"
    save_state(state, path)
    restored = load_state(path)
    assert restored.config == state.config
    np.testing.assert_array_equal(restored.x, state.x)
    np.testing.assert_array_equal(ask(restored), ask(state))
    # Pure: asking twice gives the same batch; a different seed a different one.
    np.testing.assert_array_equal(ask(state), ask(state))
    other = state._replace(config=config(seed=8))
    assert not np.allclose(ask(other), ask(state))


def test_state_file_is_plain_npz_without_pickle(tmp_path):
    path = tmp_path / "state.npz"
    save_state(run(init(config()), 2), path)
    with np.load(path, allow_pickle=False) as data:
        assert set(data.files) == {"x", "y", "config_json"}
    bad = tmp_path / "bad.npz"
    np.savez(bad, x=np.zeros((1, 2)))
    with pytest.raises(ValueError, match="lacks"):
        load_state(bad)


def test_state_file_of_format_1_with_a_flat_config_is_read(tmp_path):
    import json

    state = run(init(config()), 2)
    cfg = state.config
    flat = {**{k: getattr(cfg, k) for k in PROBLEM if k != "ref_point"}, **cfg.acquisition.to_dict()}
    for new in ("learning_rate", "scalarization", "ref_margin"):  # format 1 could not set them
        del flat[new]
    path = tmp_path / "old.npz"
    np.savez(path, x=state.x, y=state.y,
             config_json=np.array(json.dumps({"format": "mjxskill.gp.MOBOState/1", "config": flat})))
    assert load_state(path).config == cfg
    np.savez(path, x=state.x, y=state.y,
             config_json=np.array(json.dumps({"format": "mjxskill.gp.MOBOState/1", "config": {**flat, "n_raw": 0}})))
    with pytest.raises(ValueError, match="old.npz: acquisition setting n_raw: expected a positive integer"):
        load_state(path)


def test_a_state_written_before_the_closed_form_keeps_the_directions(tmp_path):
    import json

    cfg = MOBOConfig([[0.0] * 3, [1.0] * 3], 3, n_init=4, batch_size=2, ref_point=(2.0, 2.0, 2.0),
                     acquisition=acquisition_defaults(2, reference_given=True))
    path = tmp_path / "state.npz"
    save_state(tell(init(cfg), np.full((4, 3), 0.5), np.ones((4, 3))), path)
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["config_json"]))
    del meta["config"]["acquisition"]["hypervolume_improvement"]
    np.savez(path, x=np.full((4, 3), 0.5), y=np.ones((4, 3)), config_json=np.array(json.dumps(meta)))
    assert load_state(path).config.acquisition == cfg.acquisition  # not today's closed form for three


def test_acquisition_settings_from_flat_options_parse_strings_and_name_bad_keys():
    got = acquisition_settings({"n_raw": "256", "tau": "1e-4", "model": "scalarized", "learning_rate": 0.05,
                                "fit_steps": 20.0})
    assert got == AcquisitionSettings(n_raw=256, tau=1e-4, model="scalarized", learning_rate=0.05, fit_steps=20)
    assert isinstance(got.fit_steps, int) and isinstance(got.alpha, float)
    assert acquisition_settings({}) == AcquisitionSettings() == MOBOConfig(BOUNDS, 2).acquisition
    assert MOBOConfig(BOUNDS, 2, acquisition={"n_raw": 64}).acquisition.n_raw == 64
    hash(got)  # a static argument of the jitted proposal
    with pytest.raises(ValueError, match=r"unknown acquisition setting 'bounds'; valid settings: .*n_raw.*tau"):
        acquisition_settings({"bounds": 1})
    with pytest.raises(ValueError, match="acquisition setting n_raw: expected an integer, got 'many'"):
        acquisition_settings({"n_raw": "many"})
    with pytest.raises(ValueError, match="acquisition setting model: expected one of"):
        acquisition_settings({"model": 3})


def test_minimize_names_the_acquisition_setting_when_prior_is_a_hyperparameter_prior_name():
    # minimize(prior=...) is the parameter prior; "gamma" is the acquisition setting of that name
    with pytest.raises(ValueError, match=r"prior='gamma' is not a parameter prior.*acquisition=\{'prior': 'gamma'\}"):
        minimize(lambda x: x, BOUNDS, budget=8, n_init=4, prior="gamma")


def test_a_given_reference_point_takes_more_directions_unless_the_settings_say_otherwise(tmp_path):
    from mjxskill.gp.settings import GIVEN_REFERENCE_DEFAULTS, acquisition_defaults

    inferred = MOBOConfig(BOUNDS, 2).acquisition
    given = MOBOConfig(BOUNDS, 2, ref_point=(4.0, 4.0)).acquisition
    assert (inferred.n_directions, inferred.n_draws, inferred.draw_pairing) == (64, 16, "shared")
    assert (given.n_directions, given.n_draws, given.draw_pairing) == (2048, 1, "per_direction")
    assert (given.hypervolume_improvement, given.n_raw, given.n_opt_steps) == ("directions", 1024, 100)
    assert given == acquisition_defaults(reference_given=True) == acquisition_defaults(2, reference_given=True)
    # Three objectives take the closed form and a longer search (generation 3 on).
    three = MOBOConfig([[0.0] * 3, [1.0] * 3], 3, ref_point=(4.0, 4.0, 4.0)).acquisition
    assert (three.hypervolume_improvement, three.n_raw, three.n_opt_steps, three.n_directions) == (
        "exact", 4096, 300, 2048)
    # and, from generation 4 on, half the random candidates on the bounds; two objectives not
    assert (three.raw_bounds_share, given.raw_bounds_share, inferred.raw_bounds_share) == (0.5, 0.0, 0.0)
    assert acquisition_defaults(3, reference_given=True, n_objectives=3) == dataclasses.replace(three,
                                                                                               raw_bounds_share=0.0)
    assert acquisition_defaults(2, reference_given=True, n_objectives=3) == acquisition_defaults(2, reference_given=True)
    assert MOBOConfig([[0.0] * 3, [1.0] * 3], 3).acquisition == inferred  # no given reference: no change
    # minimize resolves them once it knows the number of objectives.
    res = minimize(lambda x: np.stack([x[:, 0], 1 - x[:, 0], x[:, 1]], 1), [[0.0, 0.0], [1.0, 1.0]], budget=4,
                   n_init=4, ref_point=(2.0, 2.0, 2.0))
    assert res.state.config.acquisition == three
    assert dataclasses.replace(given, **{k: getattr(inferred, k) for k in GIVEN_REFERENCE_DEFAULTS}) == inferred
    # A mapping changes what it names over those defaults; settings given whole are kept whole.
    named = MOBOConfig(BOUNDS, 2, ref_point=(4.0, 4.0), acquisition={"n_directions": 256}).acquisition
    assert (named.n_directions, named.n_draws, named.draw_pairing) == (256, 1, "per_direction")
    assert MOBOConfig(BOUNDS, 2, ref_point=(4.0, 4.0), acquisition=AcquisitionSettings()).acquisition == inferred
    assert acquisition_defaults(1, reference_given=True) == acquisition_defaults(1)  # generation 1 had no directions
    # A saved state reads back the settings it ran with.
    state = init(MOBOConfig(BOUNDS, 2, ref_point=(4.0, 4.0), acquisition=CHEAP))
    save_state(state, tmp_path / "s.npz")
    assert load_state(tmp_path / "s.npz").config == state.config


def test_repeated_asks_with_growing_data_do_not_retrace_within_a_bucket(monkeypatch):
    counted = jax.jit(chex.assert_max_traces(propose_batch.__wrapped__, n=1), static_argnames=("q", "settings"))
    monkeypatch.setattr(opt_mod, "propose_batch", counted)
    state = run(init(config()), 2)  # 5 warm-up points
    for _ in range(3):  # 5, 8, 11, 14 observations: all in the 16-row bucket
        state = run(state, 1)
    assert len(state.x) == 14
    chex.clear_trace_counter()


def test_non_finite_objectives_are_kept_and_do_not_break_the_model():
    state = run(init(config()), 2)
    x = ask(state)
    y = objectives(x)
    y[0, 0], y[1] = np.nan, np.inf
    state = tell(state, x, y)
    assert np.isnan(state.y[5, 0]) and np.isinf(state.y[6, 1])
    nxt = ask(state)
    assert np.all(np.isfinite(nxt))
    assert not pareto_mask(state.y)[5]


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(bounds=[[0.0, 1.0], [1.0, 1.0]]), r"lower >= upper in dimension 1 \(1.0 >= 1.0\)"),
        (dict(bounds=[[0.0, 2.0], [1.0, 1.0]]), "lower >= upper in dimension 1"),
        (dict(bounds=[0.0, 1.0]), r"expected shape \(2, d\)"),
        (dict(bounds=[[0.0, np.nan], [1.0, 1.0]]), "must be finite"),
        (dict(batch_size=0), "batch_size"),
        (dict(n_init=1), "n_init"),
        (dict(model="single"), "acquisition setting model: expected one of 'hybrid', 'scalarized', 'per_objective', got 'single'"),
        (dict(ei="ucb"), "acquisition setting ei"),
        (dict(tau=0.0), "acquisition setting tau: must be > 0"),
        (dict(n_raw=0), "acquisition setting n_raw: expected a positive integer, got 0"),
        (dict(n_raw=2.5), "acquisition setting n_raw: expected an integer, got 2.5"),
        (dict(n_restarts=100), r"n_restarts \(100\) exceeds n_raw \(64\)"),
        (dict(pending="draws", model="hybrid"), "pending: 'draws' .* needs model 'per_objective'"),
        (dict(pending="draws", hypervolume_improvement="exact"), "pending: 'draws' .* hypervolume_improvement 'directions'"),
        (dict(pending="draws", draw_pairing="per_direction"), "pending: 'draws' .* draw_pairing 'shared'"),
        (dict(n_rwa=3), "unknown acquisition setting 'n_rwa'; valid settings: scalarization, alpha, reference, ref_margin"),
    ],
)
def test_bad_config_raises_clear_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        config(**kwargs)


def test_bad_tell_input_raises_clear_errors():
    state = init(config())
    with pytest.raises(ValueError, match=r"x must have shape \(q, 2\)"):
        tell(state, np.zeros((3, 3)), np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"y must have shape \(3, 2\)"):
        tell(state, np.zeros((3, 2)), np.zeros((3, 1)))
    with pytest.raises(ValueError, match="outside the bounds"):
        tell(state, np.array([[5.0, 1.0]]), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="not finite"):
        tell(state, np.array([[np.nan, 1.0]]), np.zeros((1, 2)))


def test_minimize_beats_random_search_on_a_simple_problem():
    res = minimize(objectives, BOUNDS, budget=20, batch_size=3, n_init=5, seed=0, **CHEAP)
    assert res.X.shape == (20, 2) and res.Y.shape == (20, 2)
    np.testing.assert_array_equal(res.pareto_Y, res.Y[pareto_mask(res.Y)])
    ref = [2.0, 2.0]
    rand_x = np.random.default_rng(0).random((20, 2)) * 2 + [-1.0, 0.0]
    assert hypervolume(res.Y, ref) > hypervolume(objectives(rand_x), ref)
    with pytest.raises(ValueError, match=r"f returned shape \(3,\)"):
        minimize(lambda x: x[:, 0], BOUNDS, budget=10, batch_size=3, n_init=3, **CHEAP)
