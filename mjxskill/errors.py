"""The error classes every layer raises for bad input, and the one base the command line catches.

A ``UserError`` means "what the user gave us is wrong" (a scenario file, a goal, a flag, a run
directory), never "mjxskill is broken": its message names the bad value and where it came from,
and the command line turns it into one ``error:`` line with exit code 2 (``mjxskill.cli``).
Everything else is a bug and keeps its traceback.

``quote`` is how every message shows a value the user gave: a short prefix, never a whole
file. This module imports nothing of mjxskill, so every stage can raise these without depending on
another stage.
"""

from __future__ import annotations

import re
from typing import Any


# How much of a value an error message shows (``quote``) and how long one message may be at most
# (``UserError``): a scenario of one 900 KB scalar made a 900 KB error line, and a value read from
# a file that is not what it should be (a skill library naming /etc/passwd) printed the file.
QUOTE_CHARS = 60
MAX_MESSAGE_CHARS = 2000


def quote(value, limit: int = QUOTE_CHARS) -> str:
    """``repr(value)`` for an error message, cut to its first ``limit`` characters (followed by
    ``...`` and the full length) so that no value, however long, makes a long message. Every
    message that shows a value the user gave shows it through this."""
    text = repr(value)
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text)} characters)"


def listing(names, limit: int = 20, chars: int = 40) -> str:
    """``a, b, c`` for a message listing names (the objects, types, skills a value could have
    been): each cut to ``chars`` characters, at most ``limit`` of them and how many more; ""
    when there are none."""
    names = [str(n) if len(str(n)) <= chars else f"{str(n)[:chars]}..." for n in names]
    more = f" and {len(names) - limit} more" if len(names) > limit else ""
    return ", ".join(names[:limit]) + more


def bounded(message: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``message`` cut to ``limit`` characters (a mark says so); short messages unchanged."""
    if len(message) <= limit:
        return message
    return f"{message[:limit]}... (message cut at {limit} of {len(message)} characters)"


# A word of a message longer than any path or name a message means to show: a value the user gave
# that reached the message without ``quote`` (argparse's "unrecognized arguments", a path of 100 KB)
WORD_CHARS = 300
_LONG_WORD = re.compile(rf"\S{{{WORD_CHARS + 1},}}")


def shortened(message: str, limit: int = WORD_CHARS) -> str:
    """``message`` with every run of more than ``limit`` non-blank characters cut to its first
    ``limit`` (and its length), then ``bounded``: what the command line and the page print of any
    message, whatever reached it unquoted."""
    if len(message) > WORD_CHARS:
        pattern = _LONG_WORD if limit == WORD_CHARS else re.compile(rf"\S{{{limit + 1},}}")
        message = pattern.sub(lambda m: f"{m.group()[:limit]}... ({len(m.group())} characters)", message)
    return bounded(message)


class UserError(Exception):
    """Bad input from the user; the message says what and where, at most ``MAX_MESSAGE_CHARS``
    long (a longer one is cut: the place comes first, so it survives)."""

    def __init__(self, *args):
        if args and isinstance(args[0], str):
            args = (bounded(args[0]), *args[1:])
        super().__init__(*args)


class ScenarioError(UserError, ValueError):
    """An invalid scenario file; the message names the file, the key path and the line."""


class GoalError(UserError, ValueError):
    """A goal that is not a conjunction of known facts of the scenario."""


class PlanError(UserError, ValueError):
    """No plan reaches the goal, or a plan does not fit the skill library."""


class RecordingError(UserError):
    """A recording of an executed episode that cannot be used (``mjxskill.calibration.recording``):
    the message names the file, the array and, for a value, its sample and time."""


class RunError(UserError):
    """A run directory (or a file in it) that cannot be used as asked."""


class SettingError(RunError):
    """A setting value a new run cannot take (``mjxskill.training.configure``), with what a
    caller needs to word it its own way (the command line names the flag the value came from):
    ``name``, a run setting (``mjxskill.runs.settings``) or ``"optimizer_options"``; ``value``;
    ``given``, whether the caller gave it (False: the scenario's default); ``problem``, why not."""

    def __init__(self, message: str, *, name: str, value, given: bool, problem: str):
        super().__init__(message)
        self.name, self.value, self.given, self.problem = name, value, given, problem


class ResumeConflict(RunError):
    """Values given for resuming a run that are not the run's own (``mjxskill.training.configure``):
    ``run``, the run directory; ``conflicts``, one ``(name, given, the run's own)`` per value
    refused, ``name`` being a run setting, ``"optimizer_options"`` or ``"prior"`` (given: the
    run the prior was to come from; the run's own: its stored prior)."""

    def __init__(self, message: str, *, run, conflicts: tuple[tuple[str, Any, Any], ...]):
        super().__init__(message)
        self.run, self.conflicts = run, tuple(conflicts)


class ClusterError(UserError):
    """A Ray cluster that cannot be used: not found (``auto``), not reachable at the address
    given, or refusing the connection; Ray not installed (``mjxskill.engine.native.ray_pool``); or
    asked of an engine other than the native one (``mjxskill.engine.build.connect_cluster``).
    The message names the address or the engine."""


class RequestError(UserError, ValueError):
    """A request to the explore page's server that is malformed: a value that is not a number or
    an integer, a body that is not a JSON object (``mjxskill.explore.server``; answered 400)."""


class ServerBusy(UserError):
    """A request to the explore page's server that it cannot take now, answered with ``status``:
    409, the point asked for has a rollout under way; 429, the rollout queue is full
    (``mjxskill.explore.solutions``)."""

    def __init__(self, message: str, *, status: int):
        super().__init__(message)
        self.status = status


class CommandError(UserError):
    """A command's flags or arguments that cannot be honoured (e.g. an unwritable folder)."""


class Notice(UserWarning):
    """Not an error, but what the user must be told: rows of a run set aside, a compile cache
    that is off. Issued with ``warnings.warn``; the command line prints it as one
    ``prog: warning: message`` line."""


__all__ = ["MAX_MESSAGE_CHARS", "QUOTE_CHARS", "WORD_CHARS", "bounded", "listing", "quote", "shortened", "ClusterError", "CommandError", "GoalError", "Notice", "PlanError", "RecordingError", "RequestError", "ResumeConflict", "RunError", "ScenarioError",
           "ServerBusy", "SettingError", "UserError"]
