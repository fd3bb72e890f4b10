"""Shared command-line plumbing: the task argument, and bad input reported as one line on
stderr with exit code 2 (no traceback). Used by ``mjxskill.plan`` and ``mjxskill.train`` (and
later evaluate/select).
"""

from __future__ import annotations

import argparse
import sys
from typing import Callable, Sequence

EXIT_BAD_INPUT = 2


def user_errors() -> tuple[type[BaseException], ...]:
    """Exception types that mean "the user's input is wrong", not "mjxskill is broken"."""
    from mjxskill.ebt.from_plan import PlanError
    from mjxskill.pddl_gen import GoalError
    from mjxskill.yaml_fields import ScenarioError

    errors: list[type[BaseException]] = [ScenarioError, GoalError, PlanError]
    try:
        from mjxskill import planner
    except ImportError:  # the planner is not installed: nothing of it to catch
        pass
    else:
        errors += [e for e in (getattr(planner, "Unsolvable", None), getattr(planner, "PDDLError", None)) if e]
    return tuple(errors)


class CommandError(Exception):
    """Raised by a command for bad input it found itself (e.g. an unwritable export folder)."""


def add_task_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("task", help="scenario name (push, peg) or path of a scenario YAML file")


def run(main: Callable[[argparse.Namespace], int], parser: argparse.ArgumentParser, argv: Sequence[str] | None = None) -> int:
    """Parses ``argv``, runs ``main`` and turns user errors into ``prog: error: message`` + exit 2."""
    args = parser.parse_args(argv)  # argparse itself exits 2 with a usage message
    try:
        return main(args)
    except (CommandError, *user_errors()) as err:
        message = str(err) or type(err).__name__
        print(f"{parser.prog}: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT


# -- argparse value types: a bad value becomes argparse's own "invalid value" message, exit 2 --
def int_at_least(minimum: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


positive_int = int_at_least(1)


def positive_float(text: str) -> float:
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def nonnegative_float(text: str) -> float:
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value >= 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value
