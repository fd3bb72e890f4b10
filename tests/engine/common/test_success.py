"""The success tests (a small library selectable from YAML): each kind on hand-placed states with
known answers, evaluated as each engine evaluates them (float64 on the host, float32 in JAX), and
the two evaluations against each other."""

import math

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mjxskill.engine.common.arrays import HOST, JAX
from mjxskill.engine.common.success import SUCCESS_TESTS
from mjxskill.engine.common.types import SuccessTest
from mjxskill.scenario.vocabulary import SUCCESS_KINDS

YAW_90 = (math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4))


def make(kind, **values):
    base = dict(kind=kind, object=0, target=1, position_tolerance=0.01, orientation_tolerance=math.radians(5), depth=0.01,
                hole_top=(0.0, 0.0, 0.05), hole_half_width=(0.02, 0.01), hole_round=False, region_center=(0.05, 0.0, 0.0),
                region_half=(0.01, 0.03, 0.02))
    return SuccessTest(**(base | values))


def both(test, tool, pos, quat):
    native = SUCCESS_TESTS[test.kind](test, np.asarray(tool, float), np.asarray(pos, float), np.asarray(quat, float), HOST)
    compiled = SUCCESS_TESTS[test.kind](test, jnp.asarray(tool, jnp.float32), jnp.asarray(pos, jnp.float32),
                                        jnp.asarray(quat, jnp.float32), JAX)
    return native, tuple(np.asarray(v) for v in compiled)


def test_the_registry_implements_exactly_the_vocabulary():
    assert set(SUCCESS_TESTS) == set(SUCCESS_KINDS)


@pytest.mark.parametrize("object_pos, expected", [
    ((0.50, 0.05, 0.0), True),    # the region's centre, 5 cm along the target's x = world y (yaw 90)
    ((0.52, 0.05, 0.0), True),    # 2 cm along the target's -y: inside the 3 cm half-width
    ((0.50, 0.065, 0.0), False),  # 1.5 cm along its x: outside the 1 cm half-depth
    ((0.50, 0.05, 0.025), False),  # too high
])
def test_object_in_region_is_a_box_in_the_targets_frame(object_pos, expected):
    test = make("object_in_region", orientation_tolerance=math.inf)
    native, compiled = both(test, (0, 0, 0), [object_pos, (0.5, 0.0, 0.0)], [YAW_90, YAW_90])
    assert bool(native[0]) is expected and bool(compiled[0]) is expected


def test_object_in_region_with_an_orientation_tolerance():
    test = make("object_in_region")
    turned = (math.cos(math.radians(4)), 0.0, 0.0, math.sin(math.radians(4)))  # 8 degrees about z
    native, compiled = both(test, (0, 0, 0), [(0.55, 0.0, 0.0), (0.5, 0.0, 0.0)], [turned, (1, 0, 0, 0)])
    assert not bool(native[0]) and not bool(compiled[0])
    assert native[2] == pytest.approx(math.radians(8)) and float(compiled[2]) == pytest.approx(math.radians(8), abs=1e-5)


def test_inserted_reads_the_hole_in_the_boxs_frame():
    # the hole is 4 cm wide along the box's x and 2 cm along its y; the box is turned by 90 deg
    test = make("inserted")
    box = (0.5, 0.0, 0.0)
    deep_along_box_x = (0.5, 0.015, 0.035)  # 1.5 cm along the box's x (world y), 1.5 cm deep
    deep_along_box_y = (0.485, 0.0, 0.035)  # 1.5 cm along the box's y: outside its 1 cm half-width
    for tool, expected in ((deep_along_box_x, True), (deep_along_box_y, False)):
        native, compiled = both(test, tool, [(0, 0, 0), box], [(1, 0, 0, 0), YAW_90])
        assert bool(native[0]) is expected and bool(compiled[0]) is expected
        assert native[3] == pytest.approx(0.015) and float(compiled[3]) == pytest.approx(0.015, abs=1e-6)


def test_inserted_into_a_round_hole_reads_its_radius():
    # a round hole of radius 0.0165 m (the peg's 0.015 m plus 1.5 mm): inside is a distance from
    # its axis, so a point 0.012 m along both box axes (0.0170 m away) is out although each
    # coordinate is inside the radius, as a square hole of that half-width would take it
    test = make("inserted", hole_half_width=(0.0165, 0.0165), hole_round=True)
    box = (0.5, 0.0, 0.0)
    for tool, expected in (((0.5, 0.016, 0.035), True), ((0.512, 0.012, 0.035), False),
                           ((0.5116, 0.0116, 0.035), True), ((0.5, 0.0, 0.045), False)):  # 0.0164 m; 5 mm deep
        native, compiled = both(test, tool, [(0, 0, 0), box], [(1, 0, 0, 0), YAW_90])
        assert bool(native[0]) is expected and bool(compiled[0]) is expected, tool
        assert native[1] == pytest.approx(np.hypot(tool[0] - 0.5, tool[1]))


coords = st.floats(-0.1, 0.1)
unit_quats = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.2).map(
    lambda q: tuple(np.asarray(q) / np.linalg.norm(q)))


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(sorted(SUCCESS_KINDS)), st.lists(coords, min_size=3, max_size=3),
       st.lists(coords, min_size=3, max_size=3), unit_quats, unit_quats)
def test_the_engines_agree(kind, tool, obj, q_obj, q_target):
    for round_hole in ((False, True) if kind == "inserted" else (False,)):
        _agree(make(kind, hole_round=round_hole), tool, obj, q_obj, q_target)


def _agree(test, tool, obj, q_obj, q_target):
    native, compiled = both(test, tool, [obj, (0.0, 0.0, 0.0)], [q_obj, q_target])
    np.testing.assert_allclose([float(native[1]), float(native[3])], [float(compiled[1]), float(compiled[3])], atol=2e-5)
    # float32 arccos near 1 (a small angle) is quantized to ~1e-3 rad
    assert float(native[2]) == pytest.approx(float(compiled[2]), abs=2e-3)
    margin_ok = all(abs(float(a)) > 1e-4 for a in native[1:])  # no boundary case in float32
    if margin_ok:
        assert native[0] == bool(compiled[0])
