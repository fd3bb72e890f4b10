"""The divergence test both engines share (``engine.common.health``): crafted states against the
rule written out by hand, and the host and compiled namespaces agreeing on any state."""

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mjxskill.engine.common.arrays import HOST, JAX
from mjxskill.engine.common.health import healthy_state
from mjxskill.engine.common.types import MAX_QVEL, MIN_OBJECT_Z

Z = (9, 16)  # two free objects' heights in a qpos of 17


def _rows():
    qpos, qvel = np.zeros((7, 17)), np.zeros((7, 15))
    qpos[:, Z] = 0.1
    qpos[1, 3] = np.nan  # not finite
    qvel[2, 4] = np.inf  # not finite
    qvel[3, 0] = -MAX_QVEL  # at the bound: too fast
    # "Just" in float32, so that both namespaces see the same values.
    qvel[4, 14] = np.nextafter(np.float32(MAX_QVEL), np.float32(0))  # just under: fine
    qpos[5, 16] = MIN_OBJECT_Z  # at the floor: fallen through
    qpos[6, 9] = np.nextafter(np.float32(MIN_OBJECT_Z), np.float32(1))  # just above: fine
    return qpos, qvel


def test_crafted_rows_follow_the_rule():
    qpos, qvel = _rows()
    expected = [True, False, False, False, True, False, True]
    assert healthy_state(HOST, qpos, qvel, Z).tolist() == expected
    # One row at a time (NativeEpisode.healthy's call) gives the row's value.
    assert [bool(healthy_state(HOST, qpos[i], qvel[i], Z)) for i in range(7)] == expected
    assert np.asarray(healthy_state(JAX, qpos, qvel, Z)).tolist() == expected


def test_no_free_objects_checks_only_the_state():
    qpos, qvel = _rows()
    assert healthy_state(HOST, qpos, qvel, ()).tolist() == [True, False, False, False, True, True, True]


finite_or_not = st.one_of(st.floats(-200, 200), st.sampled_from([np.nan, np.inf, -np.inf]))


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, (4, 17), elements=finite_or_not), arrays(np.float64, (4, 15), elements=finite_or_not))
def test_host_and_compiled_namespaces_agree(qpos, qvel):
    # float32 rounding can move a value across a bound; keep values off the bounds by a margin.
    with np.errstate(invalid="ignore"):
        assume(not (np.abs(np.abs(qvel) - MAX_QVEL) < 1e-3).any() and not (np.abs(qpos[:, Z] - MIN_OBJECT_Z) < 1e-3).any())
    host = healthy_state(HOST, qpos, qvel, Z)
    assert host.tolist() == np.asarray(healthy_state(JAX, qpos.astype(np.float32), qvel.astype(np.float32), Z)).tolist()
