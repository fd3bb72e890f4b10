"""The domain of a number a user gives: what values the simulator and the math can honour.

A ``Domain`` is declared once (below for the world model's physics and the task's numbers,
``mjxskill.scenario.vocabulary`` beside each reward kind for its constants), and ``Field.number`` / ``Field.vector`` check a YAML value against it when the
scenario loads, before anything runs or is written; the error names the file, key and line and
says the domain. Every domain is finite: infinities and NaN are never a value.

Why bounds at all, beyond the sign: a number the YAML allows must survive what is done with it
(a 1e-300 m size is a degenerate mesh MuJoCo refuses, a 1e30 kg mass an inertia that is no
longer positive definite, a reward constant sigma_w of 0 a division by zero, bounds of +-1e308 a
parameter range whose width overflows); each bound states its reason (``why``), and every bound
lies far outside the values of any scenario we know of.

This module imports nothing of mjxskill (the vocabulary declares its domains with it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Domain:
    """The numbers ``minimum`` .. ``maximum`` (either None: unbounded on that side, but always
    finite); ``exclusive_minimum``: the minimum itself is not allowed (> rather than >=).
    ``unit``: the value's unit, shown in messages. ``why``: the reason for the bounds, shown
    when a value is refused by one of them."""

    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    unit: str = ""
    why: str = ""

    def problem(self, value: float) -> str | None:
        """Why the number ``value`` is outside the domain, as ``expected ..., got ...`` (None: it
        is inside). ``value`` is an int or a float (an int may be too large for a float)."""
        try:
            finite = math.isfinite(value)
        except OverflowError:  # an integer too large for a float (10**400)
            finite = False
        if not finite:
            return f"expected a finite number, got {_show(value)}"
        low, high = self.minimum, self.maximum
        if low is not None and (value <= low if self.exclusive_minimum else value < low):
            return self._refused(self._lower_text(), value)
        if high is not None and value > high:
            return self._refused(f"a number <= {high:g}{self._unit()}", value)
        return None

    def _lower_text(self) -> str:
        low = self.minimum
        if low == 0:
            return "a positive number" if self.exclusive_minimum else "a number >= 0"
        return f"a number {'>' if self.exclusive_minimum else '>='} {low:g}{self._unit()}"

    def _refused(self, expected: str, value) -> str:
        reason = f" ({self.describe()}: {self.why})" if self.why else ""
        return f"expected {expected}, got {_show(value)}{reason}"

    def _unit(self) -> str:
        return f" {self.unit}" if self.unit else ""

    def describe(self) -> str:
        """The domain in words: ``0.0001 to 100 m``, ``> 0 s``, ``>= 0``, ``finite``."""
        low, high = self.minimum, self.maximum
        if low is not None and high is not None:
            return f"{low:g}{' (excluded)' if self.exclusive_minimum else ''} to {high:g}{self._unit()}"
        if low is not None:
            return f"{'>' if self.exclusive_minimum else '>='} {low:g}{self._unit()}"
        if high is not None:
            return f"<= {high:g}{self._unit()}"
        return f"finite{self._unit()}"


def _show(value) -> str:
    """A number for a message: a float as Python writes it, an integer cut to a short prefix."""
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:40]}... ({len(text)} digits)"


FINITE = Domain()
NONNEGATIVE = Domain(minimum=0.0)
POSITIVE = Domain(minimum=0.0, exclusive_minimum=True)

# The domains of the world model's and the task's numbers, checked
# when the scenario loads, before anything is written. Each lies far outside any scenario we know
# of (the shipped ones: sizes 1.5 mm to 2.4 m, masses 0.2-2.5 kg, frictions 0.2-0.35, positions
# within 1 m of the robot); what it keeps out is what MuJoCo or the math cannot honour.
MAX_DISTANCE = 100.0  # m: positions and offsets; the robot reaches about 0.8 m
POSITION = Domain(-MAX_DISTANCE, MAX_DISTANCE, unit="m", why="a place in the robot's world")
MIN_SIZE, MAX_SIZE = 1e-4, 100.0  # m
SIZE = Domain(MIN_SIZE, MAX_SIZE, unit="m", why="MuJoCo cannot build a shape below 0.1 mm (a degenerate mesh) and "
              "the robot handles none beyond 100 m")
# joint angles are checked against the robot's limits after this, which keeps out what no limit
# can be compared with
JOINT_ANGLE = Domain(-2 * math.pi, 2 * math.pi, unit="rad", why="a joint angle")
ANGLE_DEG = Domain(-360.0, 360.0, unit="deg", why="an angle of the pose")
JOINT_LIMIT_DEG = Domain(0.0, 360.0, exclusive_minimum=True, unit="deg", why="symmetric joint limits")
MASS = Domain(1e-6, 1e4, unit="kg", why="MuJoCo's inertia of a lighter body is not positive definite, a heavier "
              "one no robot moves")
FRICTION = Domain(0.0, 100.0, exclusive_minimum=True, why="a sliding friction coefficient")
FRICTION_RANGE = Domain(0.0, 100.0, why="a sliding friction coefficient")
STIFFNESS = Domain(0.0, 1e6, unit="N/m or Nm/rad", why="an impedance the controller can integrate")
SIGMA = Domain(0.0, MAX_DISTANCE, unit="m", why="a standard deviation of a position")
CLIP_SIGMAS = Domain(0.0, 1000.0, exclusive_minimum=True, why="standard deviations")
TOLERANCE = Domain(0.0, MAX_DISTANCE, exclusive_minimum=True, unit="m", why="a distance")
ANGLE_TOLERANCE_DEG = Domain(0.0, 180.0, exclusive_minimum=True, unit="deg", why="an angle between two poses")
DEPTH = Domain(0.0, MAX_SIZE, exclusive_minimum=True, unit="m", why="a depth into a hole")
REGION_SIZE = Domain(0.0, MAX_DISTANCE, exclusive_minimum=True, unit="m", why="a region's extent")
EXTRA = Domain(0.0, MAX_SIZE, exclusive_minimum=True, unit="m", why="a shape's dimension")
FORCE = Domain(0.0, 1e6, unit="N", why="a force bound")
# Skill parameters (defaults, bounds, the trees' numbers, manual sets, priors) in any unit: the
# optimizer scales a learnable one by its bounds' width, which must stay a finite float.
MAX_PARAMETER = 1e6
PARAMETER = Domain(-MAX_PARAMETER, MAX_PARAMETER, why="a skill parameter's value in its unit")
WEIGHT = Domain(-1e6, 1e6, why="a reward's weight; an objective sums it over every tick")
# A prior narrower than this share of its parameter's bounds is a point the optimizer's
# truncated Gaussian cannot be evaluated at (its density underflows to 0 next to the mean).
MIN_PRIOR_STD_SHARE = 1e-6

__all__ = ["Domain", "ANGLE_DEG", "ANGLE_TOLERANCE_DEG", "CLIP_SIGMAS", "DEPTH", "EXTRA", "FINITE", "FORCE",
           "FRICTION", "FRICTION_RANGE", "JOINT_ANGLE", "JOINT_LIMIT_DEG", "MASS", "MAX_DISTANCE",
           "MAX_PARAMETER", "MAX_SIZE", "MIN_PRIOR_STD_SHARE", "MIN_SIZE", "NONNEGATIVE", "PARAMETER",
           "POSITION", "POSITIVE", "REGION_SIZE", "SIGMA", "SIZE", "STIFFNESS", "TOLERANCE", "WEIGHT"]
