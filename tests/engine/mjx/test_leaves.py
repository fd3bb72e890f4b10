"""Leaf programs without physics: what each primitive writes into the controller command."""

import math

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mjxskill  # noqa: F401
from mjxskill.bt_compiled import compile_tree
from mjxskill.ebt.nodes import Status, action, parallel_fs, sequence
from mjxskill.engine.common.bindings import NOMINAL, ObjectSlot, SceneBindings
from mjxskill.engine.mjx.leaves import LeafWorld, build_leaf_programs, init_blackboard, reference_pose, tool_down_aligned, tool_yaw
from mjxskill.sim.inverse_kinematics import tool_down_quat
from mjxskill.engine.common.rotations import quat_mul

DEFAULT_STIFFNESS = (400.0, 400.0, 400.0, 50.0, 50.0, 50.0)
YAW_30 = (math.cos(math.radians(15)), 0.0, 0.0, math.sin(math.radians(15)))
BINDINGS = SceneBindings(
    slots=(ObjectSlot("Box-1", NOMINAL, -1, -1, -1, (0.5, 0.1, 0.0), YAW_30),),
    slot_of={"Box-1": 0},
    arm_qpos=tuple(range(7)),
    randomized_pairs=(),
    force_sensors=(),
)
# An insertion-like tree: set the goal, then move there with stiffness, force and spiral.
TREE = sequence(
    "insert",
    action("ElementToBBPose", "set_goal_from_object", args={"object": "Box-1", "offset": (0.0, 0.0, 0.02)}, params={"offset_x": "dx"}),
    parallel_fs(
        "move",
        action("MGSetGoalPose", "goal_pose"),
        action("ChangeStiffness", "change_stiffness", args={"stiffness": (500.0, 500.0, 0.0, 50.0, 50.0, 50.0)}),
        action("ApplyForce", "apply_force", args={"wrench": (0.0,) * 6}, params={"force_z": "force"}),
        action("OverlayMotion", "overlay_spiral", args={"radius": 0.01, "path_velocity": 0.02, "pitch": 0.002}),
        action("EEPoseDistance", "ee_pose_distance", args={"threshold": 0.03}),
    ),
)
CT = compile_tree(TREE)
PROGRAMS = build_leaf_programs(CT, ("dx", "force"), BINDINGS, DEFAULT_STIFFNESS, 0.1)
PARAMS = jnp.array([0.05, -6.0])
START_POS = jnp.array([0.4, 0.0, 0.2])
START_QUAT = jnp.asarray(tool_down_quat(0.0), jnp.float32)
WORLD = LeafWorld(START_POS, START_QUAT, jnp.array([[0.5, 0.1, 0.0]]))


def fresh():
    return init_blackboard(START_POS, START_QUAT, DEFAULT_STIFFNESS, len(CT.leaves))


def test_statuses_before_anything_ran():
    live = jnp.zeros(len(CT.leaves), bool)
    status = np.asarray(PROGRAMS.status(fresh(), WORLD, PARAMS, live)).tolist()
    # set goal succeeds at once; holders run; the distance monitor runs until it has observed.
    assert status == [Status.SUCCESS] + [Status.RUNNING] * 5


def test_all_active_leaves_write_the_command():
    active = jnp.ones(len(CT.leaves), bool)
    bb = PROGRAMS.effects(fresh(), active, active, WORLD, PARAMS)
    # world-model position + fixed offset + learnable x offset
    np.testing.assert_allclose(np.asarray(bb.goal_pos), [0.55, 0.1, 0.02], atol=1e-6)
    np.testing.assert_allclose(np.asarray(bb.mg_goal.pos), [0.55, 0.1, 0.02], atol=1e-6)
    np.testing.assert_allclose(np.asarray(bb.mg_start.pos), np.asarray(START_POS), atol=1e-6)
    assert float(bb.mg_time) == 0.0
    np.testing.assert_allclose(np.asarray(bb.stiffness), [500, 500, 0, 50, 50, 50])
    np.testing.assert_allclose(np.asarray(bb.wrench), [0, 0, -6.0, 0, 0, 0])
    assert bool(bb.spiral_on)
    np.testing.assert_allclose(np.asarray(bb.spiral_params), [0.01, 0.02, 0.002], rtol=1e-6)
    # the goal orientation is the box's yaw (30 deg) for a tool pointing down
    assert float(tool_yaw(bb.goal_quat)) == pytest.approx(math.radians(30), abs=1e-5)


def test_halted_holders_fall_back_to_defaults_and_a_running_motion_is_kept():
    active = jnp.ones(len(CT.leaves), bool)
    bb = PROGRAMS.effects(fresh(), active, active, WORLD, PARAMS)
    bb = bb._replace(mg_time=jnp.float32(1.5))
    idle = jnp.zeros(len(CT.leaves), bool)
    later = PROGRAMS.effects(bb, idle, idle, WORLD, PARAMS)
    np.testing.assert_allclose(np.asarray(later.stiffness), DEFAULT_STIFFNESS)
    np.testing.assert_allclose(np.asarray(later.wrench), 0.0)
    assert not bool(later.spiral_on)
    assert float(later.mg_time) == 1.5  # the reference stays where the motion took it
    assert np.asarray(later.leaf_ticks).tolist() == [0] * len(CT.leaves)
    # running on (active, not started) does not restart the trajectory
    on = PROGRAMS.effects(bb, active, idle, WORLD, PARAMS)
    assert float(on.mg_time) == 1.5 and np.asarray(on.leaf_ticks).tolist() == [2] * len(CT.leaves)


def test_distance_monitor_needs_to_have_been_running():
    active = jnp.ones(len(CT.leaves), bool)
    bb = PROGRAMS.effects(fresh(), active, active, WORLD, PARAMS)
    near = WORLD._replace(tool_pos=jnp.array([0.55, 0.1, 0.04]))  # 2 cm from the goal
    monitor = len(CT.leaves) - 1
    assert int(PROGRAMS.status(bb, near, PARAMS, jnp.zeros(len(CT.leaves), bool))[monitor]) == Status.RUNNING
    assert int(PROGRAMS.status(bb, near, PARAMS, jnp.ones(len(CT.leaves), bool))[monitor]) == Status.SUCCESS
    far = WORLD._replace(tool_pos=jnp.array([0.55, 0.1, 0.1]))
    assert int(PROGRAMS.status(bb, far, PARAMS, jnp.ones(len(CT.leaves), bool))[monitor]) == Status.RUNNING


def test_reference_adds_the_spiral_in_the_horizontal_plane():
    active = jnp.ones(len(CT.leaves), bool)
    bb = PROGRAMS.effects(fresh(), active, active, WORLD, PARAMS)
    bb = bb._replace(spiral=bb.spiral._replace(theta=jnp.float32(math.pi / 2), radius=jnp.float32(0.01)))
    with_spiral = reference_pose(bb).pos
    without = reference_pose(bb._replace(spiral_on=jnp.zeros((), bool))).pos
    offset = np.asarray(with_spiral - without)
    assert offset[2] == pytest.approx(0.0, abs=1e-7) and np.linalg.norm(offset) == pytest.approx(0.01, rel=1e-5)


@settings(max_examples=60, deadline=None)
@given(current=st.floats(-math.pi, math.pi), target=st.floats(-math.pi, math.pi))
def test_aligned_tool_yaw_is_the_nearest_quarter_turn_of_the_object_yaw(current, target):
    quat = tool_down_aligned(jnp.asarray(tool_down_quat(current), jnp.float32), target)
    yaw = float(tool_yaw(quat))
    # the square tool matches the object modulo a quarter turn ...
    rem = (yaw - target) % (math.pi / 2)
    assert min(rem, math.pi / 2 - rem) < 1e-4
    # ... and turns at most 45 degrees from where it is
    turn = (yaw - current + math.pi) % (2 * math.pi) - math.pi
    assert abs(turn) <= math.pi / 4 + 1e-4


@pytest.mark.parametrize("yaw_deg", [-40.0, 0.0, 17.0, 100.0])
def test_tool_down_keeps_the_current_yaw_and_aligned_turns_to_the_object(yaw_deg):
    tree = action("ElementToBBPose", "set_goal_from_object", args={"object": "Box-1", "orientation": "tool_down"})
    ct = compile_tree(tree)
    programs = build_leaf_programs(ct, (), BINDINGS, DEFAULT_STIFFNESS, 0.1)
    # A reference that is tilted a little off tool-down: the goal is straight down again.
    tilt = jnp.asarray([math.cos(0.05), math.sin(0.05), 0.0, 0.0], jnp.float32)
    start = quat_mul(jnp.asarray(tool_down_quat(math.radians(yaw_deg)), jnp.float32), tilt)
    bb = init_blackboard(START_POS, start, DEFAULT_STIFFNESS, 1)
    one = jnp.ones(1, bool)
    bb = programs.effects(bb, one, one, WORLD, jnp.zeros(0))
    expected = tool_down_quat(math.radians(yaw_deg))
    assert abs(float(np.dot(np.asarray(bb.goal_quat), expected))) == pytest.approx(1.0, abs=1e-5)


def test_an_unknown_goal_orientation_is_rejected():
    tree = action("ElementToBBPose", "set_goal_from_object", args={"object": "Box-1", "orientation": "sideways"})
    with pytest.raises(ValueError, match="orientation 'sideways' is not one of tool_down_aligned, tool_down"):
        build_leaf_programs(compile_tree(tree), (), BINDINGS, DEFAULT_STIFFNESS, 0.1)
