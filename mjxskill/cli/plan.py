"""``python -m mjxskill.plan TASK``: plan a goal and show its behavior tree.

Prints the goal, the plan, the eBT (processor symbols ``->``, ``->*``, ``?``, ``||FS``, ...) and
the learnable parameters; ``--export DIR`` writes ``domain.pddl`` and ``problem.pddl`` for any
standard planner (both or neither, never through a link, and a file of other content there only
replaced with ``--replace``).

    python -m mjxskill.plan push
    python -m mjxskill.plan peg --goal "(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)" --export out/
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from mjxskill import cli
from mjxskill.cli.args import add_task_argument
from mjxskill.errors import CommandError, RunError, quote
from mjxskill.runs.atomic_write import DISK_FAULTS
from mjxskill.runs.outputs import write_outputs

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.task import PlannedTask


def export(task: PlannedTask, folder: Path, replace: bool = False) -> tuple[Path, Path]:
    """Writes ``domain.pddl`` and ``problem.pddl`` of ``task`` into ``folder`` (created if needed)
    through the one writer (``mjxskill.runs.outputs.write_outputs``): both or neither, each
    staged and renamed into place; a file there with other content is kept (RunError naming it)
    unless ``replace``, and a link there is never written through."""
    domain, problem = folder / "domain.pddl", folder / "problem.pddl"
    outputs = {domain: task.domain_pddl.encode(), problem: task.problem_pddl.encode()}
    try:
        write_outputs(folder, outputs, replace=replace, hint="move it away, or export elsewhere", flag="--replace")
    except OSError as err:
        if err.errno in DISK_FAULTS:  # the machine's, not the input's: the command says so (exit 1)
            raise
        raise CommandError(f"cannot write the PDDL files to {quote(str(folder), 300)}: {err.strerror}") from None
    except RunError as err:  # a link, a file of the user's: named, nothing written
        raise CommandError(f"cannot write the PDDL files to {quote(str(folder), 300)}: {err}") from None
    return domain, problem


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.plan", description="Plan a goal and show its behavior tree.")
    add_task_argument(parser)
    parser.add_argument("--goal", help="PDDL goal, e.g. \"(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)\"; default: the scenario's")
    parser.add_argument("--export", type=Path, metavar="DIR", help="write domain.pddl and problem.pddl into DIR")
    parser.add_argument("--replace", action="store_true", help="with --export: replace PDDL files in DIR that hold other "
                        "content; without it they are kept and the export is refused")
    return parser


def _main(args: argparse.Namespace) -> int:
    # lazy: the scenario loader imports mujoco (~0.3 s); plan --help takes 0.13 s without it
    from mjxskill.scenario import load_scenario
    from mjxskill.task import describe, plan_task

    scn = load_scenario(args.task)
    task = plan_task(scn, args.goal)
    print(describe(scn, task))
    if args.export is not None:
        for path in export(task, args.export, args.replace):
            print(f"wrote {path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)
