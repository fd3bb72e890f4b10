"""The command line: one module per command (``plan``, ``train``, ``evaluate``, ``select``, ``explore``) over
the library, and the one edge where bad input becomes a message.

``run`` parses the arguments, switches on the compile caches and runs the command; any
``mjxskill.errors.UserError`` (a bad scenario, goal, flag or run directory) is printed as one
``prog: error: message`` line on stderr with exit code 2, without a traceback, and a
``mjxskill.errors.Notice`` warning (rows set aside on resume, a cache that is off) as one
``prog: warning: message`` line. A fault of the machine mid-run, an ``OSError`` (a full disk,
a file system gone read-only), is one ``prog: error:`` line naming the path, with exit code 1:
what was finished is on disk (every file is appended or replaced whole,
``mjxskill.runs.atomic_write``) and the line says to run the command again; a path the system
cannot use (a name too long, a loop of links) is the user's: exit code 2. Every line is
``mjxskill.errors.shortened`` (argparse's own messages too: "unrecognized arguments" echoes a
value whole), so that no value, however long, makes a long line. A Ctrl-C ends the command with exit code 130
(``mjxskill.cli.interrupt``). Nothing below this package prints errors or exits.
"""

from __future__ import annotations

import argparse
import errno
import sys
import warnings
from typing import Callable, NoReturn, Sequence

from mjxskill._runtime import enable_compilation_cache, xla_flags_problem
from mjxskill.cli import interrupt
from mjxskill.cli.interrupt import EXIT_INTERRUPTED
from mjxskill.errors import Notice, UserError, shortened

EXIT_BAD_INPUT = 2
EXIT_FAULT = 1
# faults that freeing space or a fixed disk cures: the command is then run again
SPACE = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


# an OSError about the path the user gave, not a fault of the machine: bad input (exit 2)
BAD_PATH = (errno.ENAMETOOLONG, errno.ELOOP)


def fault_message(err: OSError) -> str:
    """One line for an OSError that ended a command mid-run."""
    where = f" ({err.filename})" if err.filename else ""  # a path of any length: the line is shortened
    what = err.strerror or str(err) or type(err).__name__
    cure = "free some space" if err.errno in SPACE else "fix that"
    return (f"{what}{where}; nothing finished is lost (what was written is whole): {cure}, then run the command "
            "again (train and experiment: with --resume)")


def run(main: Callable[[argparse.Namespace], int], parser: argparse.ArgumentParser, argv: Sequence[str] | None = None) -> int:
    """Parses ``argv``, runs ``main`` and turns user errors into ``prog: error: message`` + exit 2."""
    error = parser.error

    def short_error(message: str) -> NoReturn:  # argparse echoes values: "unrecognized arguments: ..."
        error(shortened(message))

    parser.error = short_error  # type: ignore[method-assign]
    args = parser.parse_args(argv)  # argparse itself exits 2 with a usage message
    with warnings.catch_warnings():
        warnings.simplefilter("always", Notice)
        default_show = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, Notice):
                print(f"{parser.prog}: warning: {shortened(str(message))}", file=sys.stderr, flush=True)
            else:
                default_show(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        try:
            problem = xla_flags_problem()  # XLA aborts on bad flags, past any except: said here
            if problem is not None:
                raise UserError(problem)
            enable_compilation_cache()
            return main(args)
        except UserError as err:
            message = shortened(" ".join((str(err) or type(err).__name__).split()))  # one line, whatever it holds
            print(f"{parser.prog}: error: {message}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except OSError as err:
            if err.errno in BAD_PATH and err.filename:  # a path of the user's the system cannot use
                print(f"{parser.prog}: error: {shortened(f'{err.filename}: {err.strerror}')}", file=sys.stderr)
                return EXIT_BAD_INPUT
            print(f"{parser.prog}: error: {shortened(' '.join(fault_message(err).split()))}", file=sys.stderr)
            return EXIT_FAULT
        except KeyboardInterrupt:
            interrupt.acknowledge()
            print(f"\n{parser.prog}: {interrupt.message()}", file=sys.stderr)
            return EXIT_INTERRUPTED


__all__ = ["EXIT_BAD_INPUT", "EXIT_FAULT", "EXIT_INTERRUPTED", "interrupt", "run"]
