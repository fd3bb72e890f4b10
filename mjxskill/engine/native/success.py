"""The success tests of ``mjxskill.scenario.vocabulary.SUCCESS_KINDS`` in numpy for the native engine:
one function per kind, as ``mjxskill.engine.mjx.success`` (same arguments, floats out)."""

from __future__ import annotations

import numpy as np

from mjxskill.engine.native.motion import quat_angle, quat_conj, quat_rotate


def _in_frame(quat, vector) -> np.ndarray:
    return quat_rotate(quat_conj(quat), vector)


def object_at_pose(test, tool_pos, slot_pos, slot_quat):
    d_pos = float(np.linalg.norm(slot_pos[test.object, :2] - slot_pos[test.target, :2]))
    d_rot = quat_angle(slot_quat[test.object], slot_quat[test.target])
    return d_pos < test.position_tolerance and d_rot < test.orientation_tolerance, d_pos, d_rot, 0.0


def inserted(test, tool_pos, slot_pos, slot_quat):
    rel = _in_frame(slot_quat[test.target], tool_pos - slot_pos[test.target]) - np.asarray(test.hole_top)
    inside = bool(np.all(np.abs(rel[:2]) < np.asarray(test.hole_half_width)))
    depth = float(-rel[2])
    return inside and depth > test.depth, float(np.linalg.norm(rel[:2])), 0.0, depth


def object_in_region(test, tool_pos, slot_pos, slot_quat):
    rel = _in_frame(slot_quat[test.target], slot_pos[test.object] - slot_pos[test.target]) - np.asarray(test.region_center)
    d_rot = quat_angle(slot_quat[test.object], slot_quat[test.target])
    inside = bool(np.all(np.abs(rel) <= np.asarray(test.region_half)))
    return inside and d_rot < test.orientation_tolerance, float(np.linalg.norm(rel[:2])), d_rot, 0.0


SUCCESS_TESTS = {"object_at_pose": object_at_pose, "inserted": inserted, "object_in_region": object_in_region}


def success(test, tool_pos, slot_pos, slot_quat):
    """(success, position error, orientation error, depth) of ``test`` (a SuccessTest)."""
    return SUCCESS_TESTS[test.kind](test, tool_pos, slot_pos, slot_quat)
