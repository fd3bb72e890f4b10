"""The domain of a number a user gives: what values the simulator and the math can honour.

A ``Domain`` is declared once, beside what it bounds (``mjxskill.scenario.schema`` for the world
model's physics and the task's numbers, ``mjxskill.scenario.vocabulary`` for the reward
constants), and ``Field.number`` / ``Field.vector`` check a YAML value against it when the
scenario loads, before anything runs or is written; the error names the file, key and line and
says the domain. Every domain is finite: infinities and NaN are never a value.

Why bounds at all, beyond the sign: a number the YAML allows must survive what is done with it
(a 1e-300 m size is a degenerate mesh MuJoCo refuses, a 1e30 kg mass an inertia that is no
longer positive definite, a reward constant sigma_w of 0 a division by zero, bounds of +-1e308 a
parameter range whose width overflows); each bound states its reason (``why``), and every bound
lies far outside the values of any scenario we know of.

This module imports nothing of mjxskill (the vocabulary and the schema declare domains with it).
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

__all__ = ["Domain", "FINITE", "NONNEGATIVE", "POSITIVE"]
