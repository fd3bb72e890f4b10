"""``python -m mjxskill.select DIR``: pick a Pareto solution, export it, render it.

    python -m mjxskill.select runs/push-0                    # list the Pareto front
    python -m mjxskill.select runs/push-0 --pick 2           # row 2 of pareto.csv
    python -m mjxskill.select runs/push-0 --max-force 20     # the most successful whose tool pressed < 20 N
    python -m mjxskill.select runs/push-0 --pick 2 --format mp4 --config-index 1
    python -m mjxskill.select runs/peg-exp --max-force 5     # over every run of an experiment

DIR may be a repeated run or an experiment (``mjxskill.runs.layout``): the fronts of all its
runs are listed in one table (# numbers every row, ``run`` names the run and its row), ``--pick``
and the constraints choose from all of them, and the export goes to
``DIR/selected-<kind>-<seed>-<row>/``. An export is written whole or not at all, never through
a link below DIR (or ``--out``), and replaces files of other content only with ``--replace``
(``mjxskill.evaluation.selection.write_export``). Where the runs' picks were validated
(``evaluation/validation.json``), the table has their validation success and a pick by
constraint takes a validated solution first.

The rule of a pick by constraint and the export format: ``mjxskill.evaluation.selection``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Sequence

from mjxskill import cli
from mjxskill.cli import args as cli_args
from mjxskill._headless import default_gl


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.select", description="Pick a Pareto solution, export its parameters and render it.")
    parser.add_argument("run", type=Path, help="run, repeated run or experiment directory")
    pick = parser.add_argument_group("choice (none: list the front)")
    pick.add_argument("--pick", type=cli_args.int_at_least(0), metavar="K", help="row K of the listed front (of pareto.csv for one run)")
    pick.add_argument("--max-force", type=cli_args.nonnegative_float, metavar="N", help="peak measured contact force of the tool (mean over worlds) at most N newtons")
    pick.add_argument("--min-success", type=cli_args.nonnegative_float, metavar="RATE", help="success rate at least RATE (0-1)")
    parser.add_argument("--out", type=Path, help="export folder (default RUN_DIR/selected-<K>)")
    parser.add_argument("--no-render", action="store_true", help="export the parameters only")
    parser.add_argument("--replace", action="store_true", help="replace export files that hold other content (an earlier "
                        "pick, frames of another rendering); without it they are kept and the export is refused")
    parser.add_argument("--format", choices=("png", "mp4"), default="png", help="PNG frames (default) or an MP4 (needs ffmpeg)")
    parser.add_argument("--config-index", type=cli_args.int_at_least(0), default=0, help="known start configuration to render from (default 0)")
    parser.add_argument("--seed", type=cli_args.seed_type(), default=0, help="seed of the rendered world's randomization")
    parser.add_argument("--size", type=cli_args.int_in(1, cli_args.MAX_FRAME_SIDE), nargs=2, default=(640, 480), metavar=("W", "H"), help="frame size in pixels")
    return parser


def _run(args: argparse.Namespace, prog: str) -> int:
    # lazy: the command's work imports mujoco, which reads MUJOCO_GL once, when imported: after
    # main's default_gl() (importing this module, and select --help, import no more than before)
    from mjxskill.cli import select_front

    return select_front.select(args, prog)


def main(argv: Sequence[str] | None = None) -> int:
    # Headless rendering needs MUJOCO_GL before mujoco is imported, and building the parser
    # imports it (--seed's bounds come from the scenario schema): so before anything else.
    default_gl()
    parser = build_parser()
    return cli.run(lambda args: _run(args, parser.prog), parser, argv)
