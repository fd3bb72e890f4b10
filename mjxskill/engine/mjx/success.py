"""The success tests of ``mjxskill.scenario.vocabulary.SUCCESS_KINDS`` in JAX: one function per kind
(a registry, as ``mjxskill.engine.native.success`` keeps for the native engine), evaluated on the
world's state at the end of the episode.

Each maps (test, tool_pos (3,), slot_pos (K, 3), slot_quat (K, 4)) to (success, position error m,
orientation error rad, insertion depth m); the test is ``mjxskill.engine.common.types.SuccessTest``.
"""

from __future__ import annotations

import jax.numpy as jnp

from mjxskill.engine.common.rotations import quat_angle, quat_conj, quat_rotate


def _in_frame(quat, vector):
    """``vector`` (3,) expressed in the frame turned by ``quat`` (4,)."""
    return quat_rotate(quat_conj(quat), vector)


def object_at_pose(test, tool_pos, slot_pos, slot_quat):
    d_pos = jnp.linalg.norm(slot_pos[test.object, :2] - slot_pos[test.target, :2])
    d_rot = quat_angle(slot_quat[test.object], slot_quat[test.target])
    return (d_pos < test.position_tolerance) & (d_rot < test.orientation_tolerance), d_pos, d_rot, jnp.float32(0.0)


def inserted(test, tool_pos, slot_pos, slot_quat):
    # the tool tip in the hole's frame, origin at the centre of its opening
    rel = _in_frame(slot_quat[test.target], tool_pos - slot_pos[test.target]) - jnp.asarray(test.hole_top, jnp.float32)
    inside = jnp.all(jnp.abs(rel[:2]) < jnp.asarray(test.hole_half_width, jnp.float32))
    depth = -rel[2]
    return inside & (depth > test.depth), jnp.linalg.norm(rel[:2]), jnp.float32(0.0), depth


def object_in_region(test, tool_pos, slot_pos, slot_quat):
    rel = _in_frame(slot_quat[test.target], slot_pos[test.object] - slot_pos[test.target])
    rel = rel - jnp.asarray(test.region_center, jnp.float32)
    d_rot = quat_angle(slot_quat[test.object], slot_quat[test.target])
    inside = jnp.all(jnp.abs(rel) <= jnp.asarray(test.region_half, jnp.float32))
    return inside & (d_rot < test.orientation_tolerance), jnp.linalg.norm(rel[:2]), d_rot, jnp.float32(0.0)


SUCCESS_TESTS = {"object_at_pose": object_at_pose, "inserted": inserted, "object_in_region": object_in_region}


def success(test, tool_pos, slot_pos, slot_quat):
    """(success, position error, orientation error, depth) of ``test`` (a SuccessTest)."""
    return SUCCESS_TESTS[test.kind](test, tool_pos, slot_pos, slot_quat)
