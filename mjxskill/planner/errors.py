"""Errors raised by the planner: bad PDDL input and problems without a plan."""

from __future__ import annotations

from mjxskill.errors import UserError


class PDDLError(UserError, ValueError):
    """Malformed or unsupported PDDL.

    The message starts with where the problem is (``domain, line L, column C:``) and then says
    what is wrong, so that a user can go straight to the offending text.

    Attributes:
      source: ``"domain"`` or ``"problem"`` (which text the error is in).
      line, column: 1-based position of the offending text, or None when it cannot be located.
    """

    def __init__(self, source: str, line: int | None, column: int | None, what: str):
        self.source = source
        self.line = line
        self.column = column
        self.what = what
        where = f"{source}, line {line}, column {column}" if line is not None else source
        super().__init__(f"PDDL {where}: {what}")


class Unsolvable(UserError):
    """The problem is well formed but no sequence of actions reaches the goal."""
