"""Native blackboards for property tests: a hypothesis strategy of a blackboard's motion, time
and spiral (``BLACKBOARD``), the blackboard it describes (``blackboard``), and a ``RowsBoard``
whose rows hold what given blackboards hold (``board_of``)."""

import numpy as np
from hypothesis import strategies as st

from mjxskill.engine.native.blackboard import NativeBlackboard
from mjxskill.engine.native.board import RowsBoard
from mjxskill.engine.native.motion import LinearMotion

finite = unit = st.floats(-1.0, 1.0, allow_nan=False)
START_QUAT = (0.0, 1.0, 0.0, 0.0)
# A blackboard's motion, time and spiral (``blackboard``'s arguments).
BLACKBOARD = dict(
    start=st.tuples(finite, finite, finite), goal_offset=st.tuples(finite, finite, finite),
    turn=st.tuples(unit, unit, unit, unit).filter(lambda q: sum(x * x for x in q) > 1e-3),
    elapsed=st.floats(0.0, 3.0), spiral=st.booleans(), theta=st.floats(0.0, 60.0), radius=st.floats(0.0, 0.01),
    spiral_params=st.tuples(st.floats(0.0, 0.01), st.floats(1e-4, 0.05), st.floats(0.0, 0.005)),
)


def blackboard(start, goal_offset, turn, elapsed, spiral, theta, radius, spiral_params):
    """A blackboard ``elapsed`` s into a motion from ``start`` (scaled by 0.5) by ``goal_offset``
    (scaled by 0.1), turning from START_QUAT to ``turn`` (normalized), with its spiral as given."""
    q0 = np.array(START_QUAT)
    bb = NativeBlackboard(np.array(start) * 0.5, q0, np.full(6, 400.0), 2)
    bb.motion = LinearMotion(bb.goal_pos, q0, bb.goal_pos + 0.1 * np.array(goal_offset),
                             np.array(turn) / np.linalg.norm(turn))
    bb.mg_time, bb.spiral_on, bb.spiral_params = elapsed, spiral, spiral_params
    bb.spiral_theta, bb.spiral_radius = theta, radius
    return bb


def board_of(bbs):
    """A ``RowsBoard`` whose rows hold what the blackboards ``bbs`` hold."""
    board = RowsBoard(np.stack([bb.goal_pos for bb in bbs]), np.stack([bb.goal_quat for bb in bbs]), np.full(6, 400.0),
                      len(bbs[0].leaf_ticks), np.zeros((len(bbs), 1)))
    board.motions = [bb.motion for bb in bbs]
    board.motion_rows = np.stack([bb.motion.row for bb in bbs])
    board.motion_goal = np.stack([bb.motion.goal_pos for bb in bbs])
    board.mg_time = np.array([bb.mg_time for bb in bbs])
    board.spiral_on = np.array([bb.spiral_on for bb in bbs])
    board.spiral_theta, board.spiral_radius = np.array([bb.spiral_theta for bb in bbs]), np.array([bb.spiral_radius for bb in bbs])
    board.spiral_params = np.array([bb.spiral_params for bb in bbs], float)
    board.spiral_axes = np.array([np.stack(bb.spiral_axes) for bb in bbs])
    board.leaf_ticks = np.array([bb.leaf_ticks for bb in bbs])
    return board
