"""The primitives' new inputs in both engines' leaf programs, without physics:
the tool's orientation (tilt about the turned frame's axes, a yaw offset; learnable) and the
plane of the search spiral. References: the closed-form rotation Rz Ry Rx of the tool pointing
down, and the other engine."""

import math

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mjxskill  # noqa: F401
from mjxskill.bt_compiled import compile_tree
from mjxskill.ebt.nodes import action
from mjxskill.engine.native.blackboard import NativeBlackboard
from mjxskill.engine.native.leaves import build_native_leaves
from mjxskill.engine.common.bindings import NOMINAL, ObjectSlot, SceneBindings
from mjxskill.engine.mjx.leaves import LeafWorld, build_leaf_programs, init_blackboard, reference_pose
from mjxskill.sim.inverse_kinematics import tool_down_quat

STIFFNESS = (400.0, 400.0, 400.0, 50.0, 50.0, 50.0)
YAW_30 = (math.cos(math.radians(15)), 0.0, 0.0, math.sin(math.radians(15)))
BINDINGS = SceneBindings(slots=(ObjectSlot("Box-1", NOMINAL, -1, -1, -1, (0.5, 0.1, 0.0), YAW_30),),
                         slot_of={"Box-1": 0}, arm_qpos=tuple(range(7)), randomized_pairs=(), force_sensors=())
START_POS = np.array([0.4, 0.0, 0.2])


def _rotation(quat) -> np.ndarray:
    w, x, y, z = quat
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _goal_quats(leaf, params, names, start_yaw: float = 0.0):
    """The goal quaternion the leaf writes on each engine (compiled, native)."""
    start = np.asarray(tool_down_quat(start_yaw), float)
    programs = build_leaf_programs(compile_tree(leaf), names, BINDINGS, STIFFNESS, 0.1)
    bb = init_blackboard(jnp.asarray(START_POS, jnp.float32), jnp.asarray(start, jnp.float32), STIFFNESS, 1)
    one = jnp.ones(1, bool)
    world = LeafWorld(jnp.asarray(START_POS, jnp.float32), jnp.asarray(start, jnp.float32), jnp.array([[0.5, 0.1, 0.0]]))
    compiled = np.asarray(programs.effects(bb, one, one, world, jnp.asarray(params, jnp.float32)).goal_quat, float)
    (_, effect), = build_native_leaves([leaf], names, BINDINGS.slot_of, np.array([[0.5, 0.1, 0.0]]), np.array([YAW_30]), 0.1)
    native_bb = NativeBlackboard(START_POS, start, STIFFNESS, 1)
    effect(native_bb, True, np.asarray(params, float))
    return compiled, native_bb.goal_quat


@settings(max_examples=30, deadline=None)
@given(roll=st.floats(-30, 30), pitch=st.floats(-30, 30), turn=st.floats(-40, 10))
def test_the_tool_tilts_and_turns_as_asked_on_both_engines(roll, pitch, turn):
    # the box is turned by 30 deg: turned by -40..10 more, the square tool's nearest aligned yaw
    # is the asked one itself (within 45 deg of the tool's yaw 0; no tie between two)
    leaf = action("ElementToBBPose", "set_goal_from_object",
                  args={"object": "Box-1", "orientation": "tool_down_aligned", "tool_roll": roll},
                  params={"tool_pitch": "S.pitch", "tool_yaw": "S.yaw"})
    compiled, native = _goal_quats(leaf, [pitch, turn], ("S.pitch", "S.yaw"))
    # Rz(object yaw + turn) Ry(pitch) Rx(roll) applied to the tool pointing down
    rz = lambda a: np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])  # noqa: E731
    ry = lambda a: np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])  # noqa: E731
    rx = lambda a: np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])  # noqa: E731
    expected = rz(math.radians(30 + turn)) @ ry(math.radians(pitch)) @ rx(math.radians(roll)) @ _rotation(tool_down_quat(0.0))
    np.testing.assert_allclose(_rotation(native), expected, atol=1e-9)
    np.testing.assert_allclose(_rotation(compiled), expected, atol=2e-6)
    # the tool axis is off the vertical by the tilt
    assert math.degrees(math.acos(min(1.0, -_rotation(native)[2, 2]))) == pytest.approx(
        math.degrees(math.acos(min(1.0, math.cos(math.radians(roll)) * math.cos(math.radians(pitch))))), abs=1e-5)


@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 0.6, 0.8)])
def test_the_spiral_runs_in_the_plane_normal_to_its_normal_on_both_engines(normal):
    leaf = action("OverlayMotion", "overlay_spiral", args={"radius": 0.02, "path_velocity": 0.1, "pitch": 0.01, "normal": normal})
    programs = build_leaf_programs(compile_tree(leaf), (), BINDINGS, STIFFNESS, 0.1)
    start = jnp.asarray(tool_down_quat(0.0), jnp.float32)
    bb = init_blackboard(jnp.asarray(START_POS, jnp.float32), start, STIFFNESS, 1)
    one = jnp.ones(1, bool)
    bb = programs.effects(bb, one, one, LeafWorld(jnp.asarray(START_POS, jnp.float32), start, jnp.zeros((1, 3))), jnp.zeros(0))
    (_, effect), = build_native_leaves([leaf], (), BINDINGS.slot_of, np.zeros((1, 3)), np.array([YAW_30]), 0.1)
    native = NativeBlackboard(START_POS, np.asarray(start, float), STIFFNESS, 1)
    effect(native, True, np.zeros(0))
    for theta, radius in ((0.3, 0.005), (2.0, 0.012), (4.0, 0.02)):
        compiled = bb._replace(spiral=bb.spiral._replace(theta=jnp.float32(theta), radius=jnp.float32(radius)))
        offset = np.asarray(reference_pose(compiled).pos) - START_POS
        native.spiral_theta, native.spiral_radius = theta, radius
        native_offset = native.reference()[0] - START_POS
        np.testing.assert_allclose(offset, native_offset, atol=1e-6)
        assert float(np.dot(native_offset, normal)) == pytest.approx(0.0, abs=1e-12)
        assert np.linalg.norm(native_offset) == pytest.approx(radius)
