"""The leaf programs' rows forms over a ``RowsBoard`` against their forms over one
``NativeBlackboard`` each, leaf by leaf: the same fields, bit for bit, on random blackboards
(motions part done, spirals on and off) and parameters."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mjxskill.engine.common.leaf_inputs import LeafInput
from mjxskill.engine.native.leaves import ApplyForce, OverlaySpiral, SetGoal, SetStiffness, StartMotion, _Reader
from mjxskill.engine.native.motion import plane_basis

from blackboards import BLACKBOARD, blackboard, board_of

PARAMS = 3  # a parameter vector of three values, each input reading one or a fixed value


def reader(choice: int, value: float) -> _Reader:
    return _Reader(LeafInput(choice, math.nan) if choice < PARAMS else LeafInput(None, value))


inputs = st.tuples(st.integers(0, PARAMS), st.floats(-0.05, 0.05))
effects = st.one_of(
    st.builds(lambda base, dx, dy, yaw, roll, pitch, tilted, object_yaw, aligned: SetGoal(
        np.array(base), reader(*dx), reader(*dy), reader(*yaw), reader(*roll), reader(*pitch), tilted, object_yaw,
        aligned), st.tuples(*[st.floats(-0.5, 0.5)] * 3), inputs, inputs, inputs, inputs, inputs, st.booleans(),
        st.floats(-3.0, 3.0), st.booleans()),
    st.just(StartMotion()),
    st.builds(lambda k: SetStiffness(np.full(6, k)), st.floats(0.0, 2000.0)),
    st.builds(lambda base, axis, source: ApplyForce(np.array(base), [(axis, reader(*source))]),
              st.tuples(*[st.floats(-10.0, 10.0)] * 6), st.integers(0, 2), inputs),
    st.builds(lambda radius, velocity, pitch, normal: OverlaySpiral(reader(*radius), reader(*velocity), reader(*pitch),
                                                                     plane_basis(normal)),
              inputs, inputs, inputs, st.sampled_from([(0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.3, 0.4, 0.8)])),
)


def assert_rows_are_blackboards(board, bbs):
    for r, bb in enumerate(bbs):
        np.testing.assert_array_equal(board.goal_pos[r], bb.goal_pos)
        np.testing.assert_array_equal(board.goal_quat_of(r), bb.goal_quat)
        np.testing.assert_array_equal(board.motion_rows[r], bb.motion.row)
        np.testing.assert_array_equal(board.motion_goal[r], bb.motion.goal_pos)
        assert board.mg_time[r] == bb.mg_time and board.spiral_on[r] == bb.spiral_on
        np.testing.assert_array_equal(board.stiffness[r], bb.stiffness)
        np.testing.assert_array_equal(board.wrench[r], bb.wrench)
        if bb.spiral_on:
            assert (board.spiral_theta[r], board.spiral_radius[r]) == (bb.spiral_theta, bb.spiral_radius)
            np.testing.assert_array_equal(board.spiral_params[r], bb.spiral_params)
            np.testing.assert_array_equal(board.spiral_axes[r], np.stack(bb.spiral_axes))
        pos, quat = board.reference(np.array([r]))
        np.testing.assert_array_equal(pos[0], bb.reference()[0])
        np.testing.assert_array_equal(quat[0], bb.reference()[1])


@settings(max_examples=150, deadline=None)
@given(rows=st.lists(st.fixed_dictionaries(BLACKBOARD), min_size=1, max_size=5), program=st.lists(effects, min_size=1,
       max_size=4), seed=st.integers(0, 2**31 - 1), tick_first=st.booleans())
def test_each_effects_rows_form_does_what_it_does_to_each_rows_blackboard(rows, program, seed, tick_first):
    # A tick's effects in leaf order on the rows where each is active (fresh or not), after a
    # tick's references or not (the kept end reference read, or computed again).
    rng = np.random.default_rng(seed)
    bbs = [blackboard(**r) for r in rows]
    params = rng.uniform(-0.05, 0.05, size=(len(bbs), PARAMS))
    board = board_of(bbs)
    board.params = params
    if tick_first:
        board.references(np.arange(len(bbs)), 50, 0.002)
        for bb in bbs:
            bb.references(50, 0.002)
    for effect in program:
        active = rng.random(len(bbs)) < 0.7
        fresh = rng.random(len(bbs)) < 0.5
        on = np.flatnonzero(active)
        if len(on):
            effect.rows(board, on, fresh[on], params[on])
        for r in on:
            effect(bbs[r], bool(fresh[r]), params[r])
    assert_rows_are_blackboards(board, bbs)
