"""The motion generator of ``mjxskill.engine.mjx.motion`` in plain Python floats and numpy, for the
native-MuJoCo baseline: a straight-line trajectory with a synchronised trapezoid velocity
profile, and the Archimedes spiral overlay.

Written as a user without JAX would write it: everything that depends only on the start and goal
(lengths, duration, cruise speeds) is computed once when a motion starts; a control step only
evaluates the trapezoid at time t.
"""

from __future__ import annotations

import math

import numpy as np

from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.motion import AxisLimits, MotionLimits
from mjxskill.engine.common.rotations import quat_conj, quat_mul, quat_to_rotvec, rotvec_to_quat
from mjxskill.engine.native.kernels import motion_references


def _shape_constant(lim: AxisLimits) -> float:
    return 0.5 / lim.acc + 0.5 / lim.dec


def min_duration(distance: float, lim: AxisLimits) -> float:
    """Shortest trapezoid (or triangle) duration covering ``distance``."""
    c = _shape_constant(lim)
    if distance >= c * lim.v_max**2:
        return distance / lim.v_max + c * lim.v_max
    return 2.0 * math.sqrt(c * distance)


def cruise_speed(distance: float, duration: float, lim: AxisLimits) -> float:
    """Cruise speed covering ``distance`` in ``duration`` with ``lim``'s acc/dec."""
    c = _shape_constant(lim)
    denom = duration + math.sqrt(max(duration**2 - 4.0 * c * distance, 0.0))
    return 2.0 * distance / denom if denom > 0 else 0.0


def trapezoid_position(t: float, distance: float, duration: float, speed: float, lim: AxisLimits) -> float:
    """Distance travelled at time t (clamped to [0, duration]) at cruise ``speed``."""
    t_acc, t_dec = speed / lim.acc, speed / lim.dec
    t = min(max(t, 0.0), duration)
    if t < t_acc:
        return 0.5 * lim.acc * t**2
    if t < duration - t_dec:
        return 0.5 * lim.acc * t_acc**2 + speed * (t - t_acc)
    return distance - 0.5 * lim.dec * (duration - t) ** 2


# ``LinearMotion.row``, what the motion's reference at a time depends on, as
# ``kernels.motion_references`` reads it: start_pos (columns 0-2), start_quat (3-6), delta
# (7-9), rotvec (10-12), then length, angle, duration, speed_pos, speed_rot, the translation's
# acc and dec, the rotation's acc and dec (13-21).


def references_at(rows: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The references of N motions (their ``LinearMotion.row``, stacked (N, 22)) at times t
    (n, N), one column per motion: positions (n, N, 3) and quaternions (n, N, 4), what ``at``
    gives each motion at each time to rounding (the same formulas, compiled:
    ``kernels.motion_references``)."""
    pos, quat = np.empty(t.shape + (3,)), np.empty(t.shape + (4,))
    motion_references(np.ascontiguousarray(rows, float), np.ascontiguousarray(t, float), pos, quat)
    return pos, quat


class LinearMotion:
    """Straight-line, constant-axis motion from (start_pos (3,), start_quat (4,)) to
    (goal_pos, goal_quat); translation and rotation finish together at ``duration``."""

    def __init__(self, start_pos, start_quat, goal_pos, goal_quat, limits: MotionLimits = MotionLimits()):
        self.start_pos = np.array(start_pos, float)
        self.start_quat = np.array(start_quat, float)
        self.goal_pos = np.array(goal_pos, float)
        self.goal_quat = np.array(goal_quat, float)
        self.limits = limits
        self.delta = self.goal_pos - self.start_pos
        self.length = float(np.linalg.norm(self.delta))
        self.rotvec = quat_to_rotvec(quat_mul(self.goal_quat, quat_conj(self.start_quat, HOST), HOST), HOST)
        self.angle = float(np.linalg.norm(self.rotvec))
        self.duration = max(min_duration(self.length, limits.translation), min_duration(self.angle, limits.rotation))
        self.speed_pos = cruise_speed(self.length, self.duration, limits.translation)
        self.speed_rot = cruise_speed(self.angle, self.duration, limits.rotation)
        # what ``references_at`` reads, one row for many motions at once (columns: above)
        self.row = np.concatenate([self.start_pos, self.start_quat, self.delta, self.rotvec,
                                   [self.length, self.angle, self.duration, self.speed_pos, self.speed_rot,
                                    limits.translation.acc, limits.translation.dec, limits.rotation.acc,
                                    limits.rotation.dec]])
        # the reference at and after ``duration``, once asked for
        self._end_scalar: tuple[np.ndarray, np.ndarray] | None = None
        # ``at``'s last time inside the motion and its reference: a tick's end (the rewards) and
        # the next tick's start (a goal set from the reference) ask for the same time
        self._last: tuple[float | None, tuple[np.ndarray, np.ndarray] | None] = (None, None)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference position (3,) and quaternion (4,) at time t (s) since the start."""
        if t >= self.duration:  # clamped to the duration: the value at the end, computed once
            if self._end_scalar is None:
                self._end_scalar = self._at(self.duration)
            return self._end_scalar[0].copy(), self._end_scalar[1].copy()
        last_t, last = self._last
        if t != last_t:
            last = self._at(t)
            self._last = (t, last)
        return last[0].copy(), last[1].copy()  # type: ignore[index]  # set: t is the time stored with it

    def _at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        lim = self.limits
        if self.length > 0:
            frac_pos = trapezoid_position(t, self.length, self.duration, self.speed_pos, lim.translation) / self.length
        else:
            frac_pos = 1.0
        if self.angle > 0:
            frac_rot = trapezoid_position(t, self.angle, self.duration, self.speed_rot, lim.rotation) / self.angle
        else:
            frac_rot = 1.0
        pos = self.start_pos + frac_pos * self.delta
        quat = quat_mul(rotvec_to_quat(frac_rot * self.rotvec, HOST), self.start_quat, HOST)
        return pos, quat


def plane_basis(normal) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (3,) spanning the plane normal to ``normal`` (3,) (as ``mjxskill.engine.mjx.motion``)."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    helper = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(helper, n)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def spiral_step(theta: float, radius: float, radius_max: float, velocity: float, pitch: float, dt: float):
    """SkiREIL's Archimedes spiral, one period: returns the new (theta, radius)."""
    dtheta = velocity / (radius + 0.001) * dt
    return theta + dtheta, min(radius + dtheta * pitch / (2.0 * math.pi), radius_max)
