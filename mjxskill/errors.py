"""The error classes every layer raises for bad input, and the one base the command line catches.

A ``UserError`` means "what the user gave us is wrong" (a scenario file, a goal, a flag, a run
directory), never "mjxskill is broken": its message names the bad value and where it came from,
and the command line turns it into one ``error:`` line with exit code 2 (``mjxskill.cli``).
Everything else is a bug and keeps its traceback.

This module imports nothing of mjxskill, so every stage can raise these without depending on
another stage.
"""

from __future__ import annotations


class UserError(Exception):
    """Bad input from the user; the message says what and where."""


class ScenarioError(UserError, ValueError):
    """An invalid scenario file; the message names the file, the key path and the line."""


class GoalError(UserError, ValueError):
    """A goal that is not a conjunction of known facts of the scenario."""


class PlanError(UserError, ValueError):
    """No plan reaches the goal, or a plan does not fit the skill library."""


class RunError(UserError):
    """A run directory (or a file in it) that cannot be used as asked."""


class CommandError(UserError):
    """A command's flags or arguments that cannot be honoured (e.g. an unwritable folder)."""


class Notice(UserWarning):
    """Not an error, but what the user must be told: rows of a run set aside, a compile cache
    that is off. Issued with ``warnings.warn``; the command line prints it as one
    ``prog: warning: message`` line."""


__all__ = ["CommandError", "GoalError", "Notice", "PlanError", "RunError", "ScenarioError", "UserError"]
