"""The command line: one module per command (``plan``, ``train``, ``evaluate``, ``select``, ``explore``) over
the library, and the one edge where bad input becomes a message.

``run`` parses the arguments, switches on the compile caches and runs the command; any
``mjxskill.errors.UserError`` (a bad scenario, goal, flag or run directory) is printed as one
``prog: error: message`` line on stderr with exit code 2, without a traceback. Nothing below
this package prints errors or exits.
"""

from __future__ import annotations

import argparse
import sys
from typing import Callable, Sequence

from mjxskill.errors import UserError

EXIT_BAD_INPUT = 2


def run(main: Callable[[argparse.Namespace], int], parser: argparse.ArgumentParser, argv: Sequence[str] | None = None) -> int:
    """Parses ``argv``, runs ``main`` and turns user errors into ``prog: error: message`` + exit 2."""
    args = parser.parse_args(argv)  # argparse itself exits 2 with a usage message
    from mjxskill._runtime import enable_compilation_cache

    enable_compilation_cache()
    try:
        return main(args)
    except UserError as err:
        message = str(err) or type(err).__name__
        print(f"{parser.prog}: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT


__all__ = ["EXIT_BAD_INPUT", "run"]
