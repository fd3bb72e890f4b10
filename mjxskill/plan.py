"""Goal -> PDDL -> plan -> eBT, and the ``python -m mjxskill.plan`` command.

``plan_task(scn, goal)`` is the pipeline's front end; the command prints the goal, the plan, the
eBT (processor symbols ``->``, ``->*``, ``?``, ``||FS``, ...) and the learnable parameters, and
``--export DIR`` writes ``domain.pddl`` and ``problem.pddl`` for any standard planner.

    python -m mjxskill.plan push
    python -m mjxskill.plan peg --goal "(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)" --export out/
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from mjxskill import cli
from mjxskill.ebt.from_plan import LearnableParameter, PlanError, PlanStep, ground_plan, plan_to_tree
from mjxskill.ebt.nodes import Node, render
from mjxskill.pddl_gen import domain_pddl, goal_literals, problem_pddl
from mjxskill.scenario_schema import frozen_array

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario_schema import Scenario

Solver = Callable[[str, str], Sequence[str]]


@dataclass(frozen=True)
class PlannedTask:
    """A goal planned in a scenario.

    plan: the planner's ground actions, e.g. ("(gotolinear iiwa-1 home-1 peg-1)", ...).
    steps: the same as skills with named arguments. tree: the eBT (root ``->*``).
    parameters: the learnable parameters in parameter-vector order.
    """

    goal: str
    domain_pddl: str
    problem_pddl: str
    plan: tuple[str, ...]
    steps: tuple[PlanStep, ...]
    tree: Node
    parameters: tuple[LearnableParameter, ...]

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def bounds(self) -> np.ndarray:
        """(2, P) lower and upper bounds."""
        return frozen_array([[p.lower for p in self.parameters], [p.upper for p in self.parameters]]).reshape(2, -1)

    @property
    def defaults(self) -> np.ndarray:
        """(P,) values used when nothing is learned."""
        return frozen_array([p.default for p in self.parameters])


def plan_task(scn: "Scenario", goal: str | None = None, *, solve: Solver | None = None) -> PlannedTask:
    """Plans ``goal`` (default: the scenario's) and expands the plan into an eBT.

    solve: ``(domain_text, problem_text) -> ["(action arg ...)", ...]``; default
    ``mjxskill.planner.solve`` (optimal A*). Raises GoalError for a bad goal, the planner's
    PlanError when no plan exists (the planner's Unsolvable) or the plan does not fit the skill
    library.
    """
    goal = scn.goal if goal is None else goal
    literals = goal_literals(scn, goal)
    domain = domain_pddl(scn, negative_goal=any(not positive for positive, _, _ in literals))
    problem = problem_pddl(scn, goal)
    if solve is None:
        from mjxskill.planner import solve
    try:
        plan = tuple(solve(domain, problem))
    except _unsolvable() as err:
        raise PlanError(f"no plan reaches the goal {goal!r} from the initial state of {scn.source}: {err}") from err
    steps = ground_plan(scn, plan)
    tree, parameters = plan_to_tree(scn, steps)
    return PlannedTask(goal, domain, problem, plan, steps, tree, parameters)


def _unsolvable() -> tuple[type[BaseException], ...]:
    try:
        from mjxskill.planner import Unsolvable
    except ImportError:
        return ()
    return (Unsolvable,)


def describe(scn: "Scenario", task: PlannedTask) -> str:
    """The planned task as text for the terminal."""
    lines = [f"task: {scn.name} ({scn.source})", f"goal: {task.goal}", "plan:"]
    lines += [f"  {i}. {step}" for i, step in enumerate(task.steps, start=1)]
    lines += ["behavior tree:"] + ["  " + line for line in render(task.tree).splitlines()]
    lines.append(f"learnable parameters ({len(task.parameters)}, in parameter-vector order):")
    width = max((len(p.name) for p in task.parameters), default=0)
    for p in task.parameters:
        note = f"  {p.description}" if p.description else ""
        lines.append(f"  {p.name:<{width}}  [{p.lower:g}, {p.upper:g}] {p.unit:<4} default {p.default:g}{note}")
    return "\n".join(lines)


def export(task: PlannedTask, folder: Path) -> tuple[Path, Path]:
    """Writes ``domain.pddl`` and ``problem.pddl`` into ``folder`` (created if needed)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        domain, problem = folder / "domain.pddl", folder / "problem.pddl"
        domain.write_text(task.domain_pddl)
        problem.write_text(task.problem_pddl)
    except OSError as err:
        raise cli.CommandError(f"cannot write the PDDL files to {str(folder)!r}: {err.strerror}") from None
    return domain, problem


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.plan", description="Plan a goal and show its behavior tree.")
    cli.add_task_argument(parser)
    parser.add_argument("--goal", help="PDDL goal, e.g. \"(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)\"; default: the scenario's")
    parser.add_argument("--export", type=Path, metavar="DIR", help="write domain.pddl and problem.pddl into DIR")
    return parser


def _main(args: argparse.Namespace) -> int:
    from mjxskill.scenario import load_scenario

    scn = load_scenario(args.task)
    task = scn.task if args.goal is None else plan_task(scn, args.goal)
    print(describe(scn, task))
    if args.export is not None:
        for path in export(task, args.export):
            print(f"wrote {path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
