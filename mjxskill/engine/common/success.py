"""The success tests of ``mjxskill.scenario.vocabulary.SUCCESS_KINDS``, one function per kind (a
registry), written once for both engines and evaluated on a world's state at the end of its
episode.

Each maps (test, tool_pos (3,), slot_pos (K, 3), slot_quat (K, 4), xp) to (success, position error
m, orientation error rad, insertion depth m); the test is ``mjxskill.engine.common.types.SuccessTest``
and ``xp`` the engine's array namespace (``mjxskill.engine.common.arrays``).
"""

from __future__ import annotations

from mjxskill.engine.common.rotations import quat_angle, quat_conj, quat_rotate


def _in_frame(quat, vector, xp):
    """``vector`` (3,) expressed in the frame turned by ``quat`` (4,)."""
    return quat_rotate(quat_conj(quat, xp), vector, xp)


def object_at_pose(test, tool_pos, slot_pos, slot_quat, xp):
    d_pos = xp.linalg.norm(slot_pos[test.object, :2] - slot_pos[test.target, :2])
    d_rot = quat_angle(slot_quat[test.object], slot_quat[test.target], xp)
    return (d_pos < test.position_tolerance) & (d_rot < test.orientation_tolerance), d_pos, d_rot, xp.float_dtype(0.0)


def inserted(test, tool_pos, slot_pos, slot_quat, xp):
    # the tool tip in the hole's frame, origin at the centre of its opening
    rel = _in_frame(slot_quat[test.target], tool_pos - slot_pos[test.target], xp)
    rel = rel - xp.asarray(test.hole_top, xp.float_dtype)
    if test.hole_round:  # a static fact of the scenario: one branch is traced
        inside = xp.linalg.norm(rel[:2]) < xp.float_dtype(test.hole_half_width[0])
    else:
        inside = xp.all(xp.abs(rel[:2]) < xp.asarray(test.hole_half_width, xp.float_dtype))
    depth = -rel[2]
    return inside & (depth > test.depth), xp.linalg.norm(rel[:2]), xp.float_dtype(0.0), depth


def object_in_region(test, tool_pos, slot_pos, slot_quat, xp):
    rel = _in_frame(slot_quat[test.target], slot_pos[test.object] - slot_pos[test.target], xp)
    rel = rel - xp.asarray(test.region_center, xp.float_dtype)
    d_rot = quat_angle(slot_quat[test.object], slot_quat[test.target], xp)
    inside = xp.all(xp.abs(rel) <= xp.asarray(test.region_half, xp.float_dtype))
    return inside & (d_rot < test.orientation_tolerance), xp.linalg.norm(rel[:2]), d_rot, xp.float_dtype(0.0)


SUCCESS_TESTS = {"object_at_pose": object_at_pose, "inserted": inserted, "object_in_region": object_in_region}


def success(test, tool_pos, slot_pos, slot_quat, xp):
    """(success, position error, orientation error, depth) of ``test`` (a SuccessTest)."""
    return SUCCESS_TESTS[test.kind](test, tool_pos, slot_pos, slot_quat, xp)
