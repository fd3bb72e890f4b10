"""The compiled rollout end to end on the peg task: BT + leaf programs + controller + MJX.

The task in its square geometry (peg_square): MJX collides its box-box pairs fastest, and what
is tested here is the engine, not the peg's shape (the round peg's geometry:
tests/sim/test_build_model.py, tests/sim/test_scenes.py; its insertion on the native engine:
tests/engine/native/test_engine.py).

One compiled program (3 parameter sets x 2 worlds, 10 s episodes) serves every test here:
compiling a whole episode costs minutes on a 2-core CPU, so all calls keep that shape.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import mjxskill  # noqa: F401
from mjxskill import compile_rollout, load_scenario
from mjxskill.task import plan_task
from rollout_inputs import params_of, placed_worlds

B, W = 3, 2
SPIRAL = {"PegInsertion.force": -5.0, "PegInsertion.radius": 0.012, "PegInsertion.path_velocity": 0.03}


@pytest.fixture(scope="module")
def peg():
    scn = load_scenario("peg_square")
    return scn, compile_rollout(scn, worlds=W, episode_seconds=10.0)


def box_worlds(rollout, offsets):
    """Worlds from start configuration 0 with the box moved by the given x-y offsets (W,) and no
    other randomization."""
    return placed_worlds(rollout, [(0, {"BoxWithHole-1": offset}, None) for offset in offsets])


def test_output_shapes_and_names(peg):
    scn, rollout = peg
    assert rollout.parameter_names == plan_task(scn).parameter_names
    assert rollout.objective_names == ("insertion", "applied_force")
    out = rollout(params_of(rollout, {}, SPIRAL, {}), jax.random.key(0))
    assert out.objectives.shape == (B, 2) and out.success.shape == (B, W)
    for name, value in out.metrics.items():
        # Per-world totals only: nothing grows with the episode length.
        assert value.shape == (B, W), name
    assert {f"reward_{r.name}" for r in scn.rewards} <= set(out.metrics)


def test_objectives_are_world_means_of_weighted_reward_totals(peg):
    scn, rollout = peg
    out = rollout(params_of(rollout, {}, SPIRAL, {}), jax.random.key(0))
    expected = np.zeros((B, len(scn.objective_names)))
    for reward in scn.rewards:
        col = scn.objective_names.index(reward.objective)
        expected[:, col] += reward.weight * np.asarray(out.metrics[f"reward_{reward.name}"]).mean(axis=1)
    np.testing.assert_allclose(np.asarray(out.objectives), expected, rtol=1e-5, atol=1e-3)


def test_same_key_is_bit_identical_and_another_key_draws_other_worlds(peg):
    scn, rollout = peg
    params = params_of(rollout, {}, SPIRAL, {})
    a = rollout(params, jax.random.key(7))
    b = rollout(params, jax.random.key(7))
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    wa, wc = rollout.sample_worlds(jax.random.key(7), B), rollout.sample_worlds(jax.random.key(8), B)
    assert not np.array_equal(np.asarray(wa.object_pos), np.asarray(wc.object_pos))


def test_planner_parameters_need_an_aligned_hole_and_the_spiral_finds_an_offset_one(peg):
    """The task can succeed, and its difficulty is the paper's: pressing straight down inserts
    the peg only when the world model is exact; a spiral search copes with a 5 mm error."""
    scn, rollout = peg
    worlds = box_worlds(rollout, [(0.0, 0.0), (0.004, -0.003)])
    out = rollout.run_worlds(params_of(rollout, {}, SPIRAL, SPIRAL), worlds)
    success = np.asarray(out.success)
    assert success[0].tolist() == [True, False]
    assert success[1].tolist() == [True, True]
    depth = np.asarray(out.metrics["insertion_depth"])
    assert (depth[1] > scn.success.depth).all() and depth[0, 1] < scn.success.depth
    # The BT reports success exactly when the peg is in (its distance check is the success test).
    np.testing.assert_array_equal(np.asarray(out.metrics["bt_success"]), success)
    # Force objective: the wrench cost grows with the time the force is applied.
    assert np.all(np.asarray(out.metrics["peak_commanded_force"]) == pytest.approx(5.0))


def test_a_diverging_world_is_contained(peg):
    """A world whose state is not finite is marked failed with the worst rewards and leaves the
    other worlds and parameter sets untouched."""
    scn, rollout = peg
    params = params_of(rollout, {}, SPIRAL, SPIRAL)
    worlds = rollout.sample_worlds(jax.random.key(3), B)
    broken = worlds._replace(arm_qpos=worlds.arm_qpos.at[2, 1].set(jnp.nan))
    clean, bad = rollout.run_worlds(params, worlds), rollout.run_worlds(params, broken)
    assert bool(bad.metrics["diverged"][2, 1]) and not bool(np.asarray(bad.metrics["diverged"])[:2].any())
    assert not bool(bad.success[2, 1])
    for r, term in enumerate(rollout.episode_spec.terms):
        assert float(bad.metrics[f"reward_{term.name}"][2, 1]) == pytest.approx(term.worst_raw * rollout.setup.ticks)
    assert np.isfinite(np.asarray(bad.objectives)).all()
    for x, y in zip(jax.tree.leaves(clean.metrics), jax.tree.leaves(bad.metrics)):
        np.testing.assert_array_equal(np.asarray(x)[:2], np.asarray(y)[:2])
        np.testing.assert_array_equal(np.asarray(x)[2, 0], np.asarray(y)[2, 0])


def test_absurd_parameters_stay_finite(peg):
    """Force 1e6 N, a 1 km spiral at 1e6 m/s: the controller's rate limits and torque saturation
    keep the physics finite; whatever happens, outputs are finite and the world is failed."""
    scn, rollout = peg
    absurd = {"PegInsertion.force": -1e6, "PegInsertion.radius": 1e3, "PegInsertion.path_velocity": 1e6}
    out = rollout(params_of(rollout, absurd, SPIRAL, absurd), jax.random.key(5))
    for leaf in jax.tree.leaves(out):
        assert np.isfinite(np.asarray(leaf, dtype=float)).all()
    assert not np.asarray(out.success)[[0, 2]].any()


def test_bad_params_are_rejected_with_the_expected_shape(peg):
    _, rollout = peg
    with pytest.raises(ValueError, match=r"shape \(B, 3\)"):
        rollout(np.zeros((2, 4)), jax.random.key(0))
    with pytest.raises(ValueError, match="finite"):
        rollout(np.full((1, 3), math.nan), jax.random.key(0))
