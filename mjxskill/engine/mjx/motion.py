"""Motion generator, pure JAX: point-to-point trajectory with synchronised trapezoid velocity
profiles, Archimedes-spiral overlay and rate-limited ramps. Everything is a function of time or
of a small NamedTuple state stepped at the control rate, and vmaps over worlds.

Trapezoid profile of one axis (distance L >= 0, cruise speed v, acceleration a, deceleration d):
accelerate for v/a, cruise, decelerate for v/d. Minimum duration: T = L/v_max + c v_max with
c = 1/(2a) + 1/(2d) when L >= c v_max^2, else triangular, T = 2 sqrt(c L). Synchronisation: both
translation and rotation take the longer of their minimum durations T; the faster axis gets the
cruise speed that makes its own trapezoid last exactly T (smaller root of c v^2 - T v + L = 0,
written as v = 2L / (T + sqrt(T^2 - 4cL)) to avoid cancellation).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp

from mjxskill.engine.common.motion import AxisLimits, MotionLimits
from mjxskill.engine.common.rotations import quat_conj, quat_mul, quat_to_rotvec, rotvec_to_quat


def _shape_constant(lim: AxisLimits) -> float:
    return 0.5 / lim.acc + 0.5 / lim.dec


def min_duration(distance, lim: AxisLimits):
    """Shortest trapezoid (or triangle) duration covering ``distance`` (any shape) -> same shape."""
    c = _shape_constant(lim)
    distance = jnp.asarray(distance)
    full = distance / lim.v_max + c * lim.v_max
    triangle = 2.0 * jnp.sqrt(c * distance)
    return jnp.where(distance >= c * lim.v_max**2, full, triangle)


def cruise_speed(distance, duration, lim: AxisLimits):
    """Cruise speed of the trapezoid with ``lim``'s acc/dec that covers ``distance`` in
    ``duration`` (duration >= min_duration(distance))."""
    c = _shape_constant(lim)
    disc = jnp.sqrt(jnp.maximum(duration**2 - 4.0 * c * distance, 0.0))
    denom = duration + disc
    return jnp.where(denom > 0, 2.0 * distance / jnp.where(denom > 0, denom, 1.0), 0.0)


def trapezoid_position(t, distance, duration, lim: AxisLimits):
    """Distance travelled at time t on the trapezoid (distance, duration); clamps outside
    [0, duration]. Scalars or broadcastable arrays."""
    v = cruise_speed(distance, duration, lim)
    t_acc, t_dec = v / lim.acc, v / lim.dec
    t = jnp.clip(t, 0.0, duration)
    accel = 0.5 * lim.acc * t**2
    cruise = 0.5 * lim.acc * t_acc**2 + v * (t - t_acc)
    decel = distance - 0.5 * lim.dec * (duration - t) ** 2
    return jnp.where(t < t_acc, accel, jnp.where(t < duration - t_dec, cruise, decel))


class Pose(NamedTuple):
    pos: jnp.ndarray  # (3,) m
    quat: jnp.ndarray  # (4,) w x y z


def trajectory_duration(start: Pose, goal: Pose, limits: MotionLimits = MotionLimits()):
    """Duration (scalar) of the synchronised linear motion from start to goal."""
    length = jnp.linalg.norm(goal.pos - start.pos)
    angle = jnp.linalg.norm(quat_to_rotvec(quat_mul(goal.quat, quat_conj(start.quat))))
    return jnp.maximum(min_duration(length, limits.translation), min_duration(angle, limits.rotation))


def linear_trajectory(start: Pose, goal: Pose, t, limits: MotionLimits = MotionLimits()) -> Pose:
    """Reference pose at time t (s, scalar) of the straight-line, constant-axis motion from
    ``start`` to ``goal``; translation and rotation both finish at trajectory_duration."""
    duration = trajectory_duration(start, goal, limits)
    delta = goal.pos - start.pos
    length = jnp.linalg.norm(delta)
    rotvec = quat_to_rotvec(quat_mul(goal.quat, quat_conj(start.quat)))
    angle = jnp.linalg.norm(rotvec)
    s_pos = trapezoid_position(t, length, duration, limits.translation)
    s_rot = trapezoid_position(t, angle, duration, limits.rotation)
    frac_pos = jnp.where(length > 0, s_pos / jnp.where(length > 0, length, 1.0), 1.0)
    frac_rot = jnp.where(angle > 0, s_rot / jnp.where(angle > 0, angle, 1.0), 1.0)
    pos = start.pos + frac_pos * delta
    quat = quat_mul(rotvec_to_quat(frac_rot * rotvec), start.quat)
    return Pose(pos, quat)


class SpiralState(NamedTuple):
    theta: jnp.ndarray  # () float: polar angle, rad
    radius: jnp.ndarray  # () float: current radius, m


def init_spiral(dtype=jnp.float32) -> SpiralState:
    return SpiralState(jnp.zeros((), dtype), jnp.zeros((), dtype))


def spiral_step(state: SpiralState, radius_max, path_velocity, pitch, dt) -> SpiralState:
    """SkiREIL's Archimedes spiral: dtheta = v / (r + 0.001) dt, dr = dtheta pitch / (2 pi),
    r capped at radius_max (the 1 mm keeps the first step finite)."""
    dtheta = path_velocity / (state.radius + 0.001) * dt
    radius = jnp.minimum(state.radius + dtheta * pitch / (2.0 * math.pi), radius_max)
    return SpiralState(state.theta + dtheta, radius)


def plane_basis(normal):
    """Two unit vectors (3,), (3,) spanning the plane normal to ``normal`` (3,)."""
    n = normal / jnp.linalg.norm(normal)
    # Cross with the world axis least aligned with n: never degenerate.
    helper = jnp.where(jnp.abs(n[2]) < 0.9, jnp.array([0.0, 0.0, 1.0], n.dtype), jnp.array([1.0, 0.0, 0.0], n.dtype))
    e1 = jnp.cross(helper, n)
    e1 = e1 / jnp.linalg.norm(e1)
    return e1, jnp.cross(n, e1)


def spiral_offset(state: SpiralState, normal):
    """Offset (3,) to add to the reference position: r (cos theta e1 + sin theta e2) in the plane
    normal to ``normal`` (z for the peg)."""
    e1, e2 = plane_basis(normal)
    return state.radius * (jnp.cos(state.theta) * e1 + jnp.sin(state.theta) * e2)


def ramp(current, target, rate, dt):
    """Moves ``current`` toward ``target`` by at most rate * dt per call (gradual stiffness and
    force changes; elementwise, any shape)."""
    step = rate * dt
    return current + jnp.clip(target - current, -step, step)
