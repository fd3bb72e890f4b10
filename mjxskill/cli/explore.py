"""``python -m mjxskill.explore RUN_DIR``: a local page to explore the Pareto front and pick a solution.

    python -m mjxskill.explore runs/push-0                 # http://127.0.0.1:8765/
    python -m mjxskill.explore runs/push-x10 --port 0      # a repeated run; any free port

The page, its API and what it writes: ``mjxskill.explore``.
"""

from __future__ import annotations

import argparse
import errno
import sys
from pathlib import Path
from typing import Sequence

from mjxskill import cli
from mjxskill._headless import default_gl
from mjxskill.cli import args as cli_args
from mjxskill.errors import CommandError
from mjxskill.runs.atomic_write import refuse_links_out
from mjxskill.runs.bounds import MAX_PER_CONFIG

LOOPBACK = ("127.0.0.1", "localhost", "::1")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.explore", description="Serve a local page to explore a run's Pareto front, "
                                     "inspect solutions in simulation and export one.")
    parser.add_argument("run", type=Path, help="run directory written by mjxskill.train (one run or a --repeats run) "
                                                 "or an experiment directory of mjxskill.experiment")
    parser.add_argument("--port", type=cli_args.port, default=8765, help="TCP port (default 8765; 0: any free port)")
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    parser.add_argument("--per-config", type=cli_args.int_in(1, MAX_PER_CONFIG), default=5,
                        help="worlds per start configuration when a solution is rolled out on demand (default 5, as evaluate)")
    parser.add_argument("--seed", type=cli_args.int_at_least(0), default=0, help="seed of those worlds and of the rendered one")
    return parser


def _main(args: argparse.Namespace) -> int:
    default_gl()  # before anything imports mujoco (the on-demand rendering)
    # lazy: these import mujoco, which reads MUJOCO_GL once, when imported (and ~0.35 s)
    from mjxskill.explore.server import Explorer, make_explore_server
    from mjxskill.explore.solutions import Solutions

    refuse_links_out(args.run)  # before anything in it is read
    explorer = Explorer(args.run, Solutions(args.run, per_config=args.per_config, seed=args.seed))
    try:
        server = make_explore_server(explorer, args.host, args.port)
    except OSError as err:
        if err.errno == errno.EADDRINUSE:
            raise CommandError(f"port {args.port} on {args.host} is in use; choose another with --port N "
                               "(0: any free port)") from None
        raise CommandError(f"cannot listen on {args.host}:{args.port}: {err.strerror or err}") from None
    host = f"[{args.host}]" if ":" in args.host else args.host
    print(f"exploring {args.run} at http://{host}:{server.server_port}/ (Ctrl-C stops)", flush=True)
    if args.host not in LOOPBACK:
        print(f"{build_parser().prog}: warning: listening on {args.host}: anyone who reaches this address can read "
              "the run directory and export from it (there is no login)", file=sys.stderr, flush=True)
    try:
        server.serve_forever()  # until Ctrl-C: its KeyboardInterrupt becomes exit code 130 in cli.run
    finally:
        server.server_close()
        explorer.close()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)
