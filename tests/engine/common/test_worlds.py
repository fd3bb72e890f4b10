"""Domain randomization: determinism per key and the distributions the scenario asks for."""

import jax
import numpy as np
import pytest

import mjxskill  # noqa: F401
from mjxskill.engine.common.bindings import FREE, MOCAP, NOMINAL, bind_scene, referenced_objects
from mjxskill.engine.common.types import leaf_objects
from mjxskill.sim.model import build_model
from mjxskill.engine.common.worlds import make_sampler, sample_worlds, worlds_per_config
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task
from scenario_texts import shipped_text, write_copy


@pytest.fixture(scope="module", params=["push", "peg", "push clipped"])
def setup(request, tmp_path_factory):
    if request.param == "push clipped":  # SkiREIL's choice, a scenario option
        text = shipped_text("push").replace("  friction_range: [0.2, 0.25]", "  clip_sigmas: 1.0\n  friction_range: [0.2, 0.25]")
        scn = load_scenario(write_copy(tmp_path_factory.mktemp("clipped"), "push", text))
        assert scn.randomization.clip_sigmas == 1.0
    else:
        scn = load_scenario(request.param)
    model = build_model(scn)
    bindings = bind_scene(scn, model, referenced_objects(scn, leaf_objects(plan_task(scn).tree)))
    return scn, bindings, make_sampler(scn, bindings)


def test_objects_bind_to_the_scene(setup):
    scn, bindings, _ = setup
    how = {s.name: s.how for s in bindings.slots}
    if scn.name == "push":
        assert how == {"ObjectToBePushed-1": FREE, "ObjectGoalPose-1": MOCAP}
    else:
        assert how["BoxWithHole-1"] == MOCAP
        assert how["Peg-1"] == NOMINAL  # rides on the flange; nothing reads its body
        assert len(bindings.force_sensors) == 1  # the peg's touch sensor (mjxskill.sim.tool_force)


def test_same_key_same_worlds_other_key_other_worlds(setup):
    _, _, sampler = setup
    a = sample_worlds(sampler, jax.random.key(3), (4, 7))
    b = sample_worlds(sampler, jax.random.key(3), (4, 7))
    c = sample_worlds(sampler, jax.random.key(4), (4, 7))
    for x, y in zip(a, b):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert not np.array_equal(np.asarray(a.object_pos), np.asarray(c.object_pos))
    assert a.arm_qpos.shape == (4, 7, 7) and a.object_pos.shape[:2] == (4, 7)


def test_randomization_statistics_match_the_scenario(setup):
    scn, bindings, sampler = setup
    worlds = sample_worlds(sampler, jax.random.key(0), (4000,))
    index = np.asarray(worlds.config_index)
    n_configs = len(scn.robot.start_configs)
    counts = np.bincount(index, minlength=n_configs)
    assert counts.min() > 4000 / n_configs * 0.85  # uniform over the start configurations
    np.testing.assert_allclose(np.asarray(worlds.arm_qpos), scn.robot.start_configs[index], atol=1e-6)
    clip = scn.randomization.clip_sigmas
    for k, slot in enumerate(bindings.slots):
        sigma = scn.randomization.xy_sigma.get(slot.name, 0.0)
        offset = np.asarray(worlds.object_pos[:, k]) - np.asarray(slot.position)
        np.testing.assert_allclose(offset[:, 2], 0.0, atol=1e-7)  # randomized in x-y only
        if sigma == 0.0:
            np.testing.assert_allclose(offset, 0.0, atol=1e-7)
            continue
        if clip is None:  # Gaussian: sd sigma, a third of the draws beyond 1 sd, 4.6 % beyond 2
            np.testing.assert_allclose(offset[:, :2].std(axis=0), sigma, rtol=0.06)
            beyond = np.abs(offset[:, :2]) / sigma
            assert np.mean(beyond > 1) == pytest.approx(0.3173, abs=0.02)
            assert np.mean(beyond > 2) == pytest.approx(0.0455, abs=0.01)
        else:
            assert np.abs(offset[:, :2]).max() <= clip * sigma + 1e-7
            # A standard normal clipped to +-c has variance erf-based; check it stays below sigma.
            assert (offset[:, :2].std(axis=0) < sigma).all()
    friction = np.asarray(worlds.friction)
    if scn.randomization.friction_range is None:
        assert np.isnan(friction).all()
    else:
        lo, hi = scn.randomization.friction_range
        assert friction.min() >= lo and friction.max() <= hi


def test_worlds_per_config_cover_every_configuration(setup):
    scn, _, sampler = setup
    worlds = worlds_per_config(sampler, jax.random.key(1), 3)
    expected = np.repeat(np.arange(len(scn.robot.start_configs)), 3)
    np.testing.assert_array_equal(np.asarray(worlds.config_index), expected)
