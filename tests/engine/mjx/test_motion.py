"""Motion generator against closed forms: trapezoid duration and peak speed,
synchronisation of translation and rotation, spiral radius growth per revolution and path
speed, ramps."""

from __future__ import annotations

import math

import mjxskill  # noqa: F401  (XLA flags before jax runs)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mjxskill.engine.mjx.motion import (
    MotionLimits, Pose, init_spiral, linear_trajectory, plane_basis, ramp, spiral_offset, spiral_step,
    trajectory_duration)
from mjxskill.engine.common.rotations import quat_mul, rotvec_to_quat

LIMITS = MotionLimits()
DT = 0.002
IDENTITY = jnp.array([1.0, 0.0, 0.0, 0.0])


@jax.jit
def _sample(start_pos, start_quat, goal_pos, goal_quat, times):
    start, goal = Pose(start_pos, start_quat), Pose(goal_pos, goal_quat)
    poses = jax.vmap(lambda t: linear_trajectory(start, goal, t))(times)
    return poses, trajectory_duration(start, goal)


def _profile(delta_pos, rotvec, t_end=8.0):
    times = jnp.arange(0.0, t_end, DT)
    start_q = jnp.array([0.9238795, 0.0, 0.3826834, 0.0])  # any non-trivial start orientation
    goal_q = jnp.asarray(np.asarray(rotvec_to_quat(jnp.asarray(rotvec, jnp.float32))))
    poses, duration = _sample(jnp.zeros(3), start_q, jnp.asarray(delta_pos, jnp.float32),
                              quat_mul(goal_q, start_q), times)
    dist = np.linalg.norm(np.asarray(poses.pos), axis=1)
    return np.asarray(times), dist, _angle_from(np.asarray(poses.quat), np.asarray(start_q)), float(duration)


def _angle_from(quats, start):
    """Rotation angles (rad) from ``start`` (4,) to each of ``quats`` (N, 4), in float64 from the
    relative rotation's vector part: arccos of the dot product is ill-conditioned near zero, so
    the quaternions' float32 rounding showed as 3e-4 rad steps (0.15 rad/s over one 2 ms step);
    ``quat_angle`` (mjxskill.engine.common.rotations, mjxskill.engine.native.motion) is such an arccos."""
    q, s = np.asarray(quats, np.float64), np.asarray(start, np.float64)
    w = q @ s
    # vector part of conj(start) * q
    v = s[0] * q[:, 1:] - q[:, :1] * s[1:] - np.cross(s[1:], q[:, 1:])
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(w))


def test_translation_trapezoid_duration_and_peak_speed():
    # 0.3 m at v 0.2, a 0.3, d 0.15: accel 0.667 s, decel 1.333 s, cruise 0.5 s -> T = 2.5 s.
    times, dist, _, duration = _profile([0.3, 0.0, 0.0], [0.0, 0.0, 0.0])
    assert duration == pytest.approx(2.5, abs=1e-5)
    speed = np.diff(dist) / DT
    assert speed.max() == pytest.approx(0.2, rel=2e-3)
    assert dist[times >= 2.5][0] == pytest.approx(0.3, abs=1e-5)
    # closed form at t = 0.5 s (accelerating) and t = 2.0 s (decelerating)
    assert dist[np.searchsorted(times, 0.5)] == pytest.approx(0.5 * 0.3 * 0.5**2, abs=1e-5)
    assert dist[np.searchsorted(times, 2.0)] == pytest.approx(0.3 - 0.5 * 0.15 * 0.5**2, abs=1e-5)


def test_short_move_is_triangular():
    # 0.01 m never reaches 0.2 m/s: T = 2 sqrt(c L), c = 1/0.6 + 1/0.3 = 5, peak sqrt(L / c).
    times, dist, _, duration = _profile([0.0, 0.01, 0.0], [0.0, 0.0, 0.0])
    assert duration == pytest.approx(2 * math.sqrt(5 * 0.01), rel=1e-5)
    assert (np.diff(dist) / DT).max() == pytest.approx(math.sqrt(0.01 / 5), rel=1e-2)


def test_rotation_dominated_move_is_synchronised():
    # 1.5 rad at 0.5 rad/s (a 0.5, d 0.35): T = 3 + 0.5 (1 + 1/0.7) / 2 = 3.607 s; the 0.1 m
    # translation is slowed to take exactly as long.
    times, dist, angle, duration = _profile([0.0, 0.0, 0.1], [0.0, 0.0, 1.5])
    expected = 1.5 / 0.5 + 0.5 * (0.5 / 0.5 + 0.5 / 0.35)
    assert duration == pytest.approx(expected, rel=1e-5)
    assert (np.diff(angle) / DT).max() == pytest.approx(0.5, rel=5e-3)
    c = 0.5 / 0.3 + 0.5 / 0.15
    v_trans = (expected - math.sqrt(expected**2 - 4 * c * 0.1)) / (2 * c)
    assert (np.diff(dist) / DT).max() == pytest.approx(v_trans, rel=5e-3)
    # both still moving just before T, both done at T
    before, after = np.searchsorted(times, duration - 0.05), np.searchsorted(times, duration + DT)
    assert dist[before] < 0.1 - 1e-5 and angle[before] < 1.5 - 1e-4
    assert dist[after] == pytest.approx(0.1, abs=1e-5) and angle[after] == pytest.approx(1.5, abs=2e-3)


@settings(max_examples=15, deadline=None)
@given(st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3),
       st.lists(st.floats(-1.2, 1.2), min_size=3, max_size=3))
def test_profiles_respect_limits_and_end_at_goal(delta, rotvec):
    times, dist, angle, duration = _profile(delta, rotvec)
    assert duration < times[-1]
    speed, rot_speed = np.diff(dist) / DT, np.diff(angle) / DT
    assert speed.max() <= 0.2 * (1 + 1e-3) + 1e-4 and rot_speed.max() <= 0.5 * (1 + 1e-3) + 2e-3
    assert dist[-1] == pytest.approx(np.linalg.norm(delta), abs=1e-5)
    assert angle[-1] == pytest.approx(np.linalg.norm(rotvec), abs=2e-3)


@jax.jit
def _spiral(radius_max, velocity, pitch):
    def body(state, _):
        state = spiral_step(state, radius_max, velocity, pitch, DT)
        return state, (state, spiral_offset(state, jnp.array([0.0, 0.0, 1.0])))

    return jax.lax.scan(body, init_spiral(), None, length=5000)[1]


def test_spiral_radius_grows_by_one_pitch_per_revolution_and_keeps_path_speed():
    radius_max, velocity, pitch = 0.05, 0.1, 0.01
    states, offsets = jax.tree.map(np.asarray, _spiral(radius_max, velocity, pitch))
    revolutions = np.floor(states.theta / (2 * np.pi))
    first = [np.argmax(revolutions >= k) for k in (2, 3, 4)]
    growth = np.diff(states.radius[first])
    np.testing.assert_allclose(growth, pitch, rtol=2e-2)
    assert states.radius.max() == pytest.approx(radius_max)
    # Path speed: tangential r dtheta/dt = v r / (r + 1 mm) plus the radial dr/dt.
    r = states.radius[1:]
    k = (r > 0.01) & (r < radius_max - 1e-4)
    speed = np.linalg.norm(np.diff(offsets, axis=0), axis=1)[k] / DT
    expected = velocity / (r[k] + 0.001) * np.sqrt(r[k] ** 2 + (pitch / (2 * np.pi)) ** 2)
    np.testing.assert_allclose(speed, expected, rtol=2e-2)
    np.testing.assert_allclose(offsets[:, 2], 0.0, atol=1e-7)  # in the plane normal to z
    capped = states.radius >= radius_max - 1e-7
    np.testing.assert_allclose(np.linalg.norm(offsets[capped], axis=1), radius_max, rtol=1e-5)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 0.1))
def test_spiral_plane_is_normal_to_the_direction(normal):
    e1, e2 = plane_basis(jnp.asarray(normal, jnp.float32))
    n = np.asarray(normal) / np.linalg.norm(normal)
    basis = np.stack([e1, e2, n])
    np.testing.assert_allclose(basis @ basis.T, np.eye(3), atol=1e-5)


def test_ramp_reaches_target_at_the_rate_limit():
    value = jnp.array([0.0, 700.0])
    target = jnp.array([700.0, 0.0])
    steps = 0
    while not np.allclose(value, target):
        value = ramp(value, target, 500.0, DT)
        steps += 1
    assert steps == 700  # 700 / (500 * 0.002)
