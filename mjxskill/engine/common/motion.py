"""The motion generator's limits, shared by both engines' motion generators
(``mjxskill.engine.mjx.motion`` in JAX, ``mjxskill.engine.native.motion`` in numpy).

SkiREIL's linear motion: translation at most 0.2 m/s, accelerating at 0.3 m/s^2 and braking at
0.15 m/s^2; rotation at most 0.5 rad/s, 0.5 and 0.35 rad/s^2.
"""

from __future__ import annotations

from typing import NamedTuple


class AxisLimits(NamedTuple):
    v_max: float  # cruise speed limit (m/s or rad/s)
    acc: float  # acceleration (m/s^2 or rad/s^2)
    dec: float  # deceleration


class MotionLimits(NamedTuple):
    translation: AxisLimits = AxisLimits(0.2, 0.3, 0.15)
    rotation: AxisLimits = AxisLimits(0.5, 0.5, 0.35)
