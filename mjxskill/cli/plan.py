"""``python -m mjxskill.plan TASK``: plan a goal and show its behavior tree.

Prints the goal, the plan, the eBT (processor symbols ``->``, ``->*``, ``?``, ``||FS``, ...) and
the learnable parameters; ``--export DIR`` writes ``domain.pddl`` and ``problem.pddl`` for any
standard planner.

    python -m mjxskill.plan push
    python -m mjxskill.plan peg --goal "(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)" --export out/
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from mjxskill import cli
from mjxskill.cli.args import add_task_argument
from mjxskill.errors import CommandError

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.task import PlannedTask


def export(task: PlannedTask, folder: Path) -> tuple[Path, Path]:
    """Writes ``domain.pddl`` and ``problem.pddl`` of ``task`` into ``folder`` (created if needed)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        domain, problem = folder / "domain.pddl", folder / "problem.pddl"
        domain.write_text(task.domain_pddl)
        problem.write_text(task.problem_pddl)
    except OSError as err:
        raise CommandError(f"cannot write the PDDL files to {str(folder)!r}: {err.strerror}") from None
    return domain, problem


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.plan", description="Plan a goal and show its behavior tree.")
    add_task_argument(parser)
    parser.add_argument("--goal", help="PDDL goal, e.g. \"(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)\"; default: the scenario's")
    parser.add_argument("--export", type=Path, metavar="DIR", help="write domain.pddl and problem.pddl into DIR")
    return parser


def _main(args: argparse.Namespace) -> int:
    # lazy: the scenario loader imports mujoco (~0.3 s); plan --help takes 0.13 s without it
    from mjxskill.scenario import load_scenario
    from mjxskill.task import describe, plan_task

    scn = load_scenario(args.task)
    task = plan_task(scn, args.goal)
    print(describe(scn, task))
    if args.export is not None:
        for path in export(task, args.export):
            print(f"wrote {path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)
