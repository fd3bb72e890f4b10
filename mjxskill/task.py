"""Goal -> PDDL -> plan -> eBT -> learnable parameters: ``plan_task(scn, goal=None)``.

The pipeline's front end, between the world model (``mjxskill.scenario``) and everything that
runs a plan (``mjxskill.engine.mjx``, ``mjxskill.engine.native``, ``mjxskill.training``). A loaded scenario
holds no plan; a ``PlannedTask`` is the plan of one goal in it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

import numpy as np

from mjxskill.ebt.from_plan import LearnableParameter, PlanStep, ground_plan, plan_to_tree
from mjxskill.ebt.nodes import Node, render
from mjxskill.errors import PlanError, ScenarioError, quote
from mjxskill.planner import Unsolvable
from mjxskill.planner import solve as optimal_solve
from mjxskill.planner.world_pddl import domain_pddl, goal_literals, problem_pddl
from mjxskill.scenario.schema import frozen_array, frozen_mapping

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario.schema import Scenario

Solver = Callable[[str, str], Sequence[str]]


@dataclass(frozen=True, eq=False)
class PlannedTask:
    """A goal planned in a scenario.

    plan: the planner's ground actions, e.g. ("(gotolinear iiwa-1 home-1 peg-1)", ...).
    steps: the same as skills with named arguments. tree: the eBT (root ``->*``).
    parameters: the learnable parameters in parameter-vector order.
    manual_parameters: name -> (P,) the scenario's operator sets that fit this plan, in
    parameter-vector order.
    """

    goal: str
    domain_pddl: str
    problem_pddl: str
    plan: tuple[str, ...]
    steps: tuple[PlanStep, ...]
    tree: Node
    parameters: tuple[LearnableParameter, ...]
    manual_parameters: Mapping[str, np.ndarray]

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def parameter_units(self) -> tuple[str, ...]:
        return tuple(p.unit for p in self.parameters)

    @property
    def bounds(self) -> np.ndarray:
        """(2, P) lower and upper bounds."""
        return frozen_array([[p.lower for p in self.parameters], [p.upper for p in self.parameters]]).reshape(2, -1)

    @property
    def defaults(self) -> np.ndarray:
        """(P,) values used when nothing is learned (the plain planner solution)."""
        return frozen_array([p.default for p in self.parameters])

    def __repr__(self) -> str:  # part of the rollout program's cache key: everything that shapes it
        return f"PlannedTask(goal={self.goal!r}, plan={self.plan!r}, tree={render(self.tree)!r}, parameters={self.parameters!r})"


def plan_task(scn: "Scenario", goal: str | None = None, *, solve: Solver | None = None) -> PlannedTask:
    """Plans ``goal`` (default: the scenario's) and expands the plan into an eBT.

    solve: ``(domain_text, problem_text) -> ["(action arg ...)", ...]``; default
    ``mjxskill.planner.solve`` (optimal A*). Raises GoalError for a bad goal and PlanError when
    no plan exists or the plan does not fit the skill library. For the scenario's own goal an
    operator set that does not fit the plan is a ScenarioError naming the set; for another goal
    the sets that do not fit are not used (they were written for another plan).
    """
    own_goal = goal is None or goal == scn.goal
    goal = scn.goal if goal is None else goal
    literals = goal_literals(scn, goal)
    domain = domain_pddl(scn, negative_goal=any(not positive for positive, _, _ in literals))
    problem = problem_pddl(scn, goal)
    if solve is None:
        solve = optimal_solve
    try:
        plan = tuple(solve(domain, problem))
    except Unsolvable as err:
        message = f"no plan reaches the goal {quote(goal)} from the initial state of {scn.source}: {err}"
        if own_goal:  # the scenario's own goal: name its place in the file
            raise ScenarioError(f"{scn.where('goal')}: {message}") from err
        raise PlanError(message) from err
    steps = ground_plan(scn, plan)
    tree, parameters = plan_to_tree(scn, steps)
    manual = _manual_sets(scn, parameters, strict=own_goal)
    return PlannedTask(goal, domain, problem, plan, steps, tree, parameters, manual)


def _manual_sets(scn: "Scenario", parameters: Sequence[LearnableParameter], strict: bool) -> Mapping[str, np.ndarray]:
    names = [p.name for p in parameters]
    sets = {}
    for set_name, manual in scn.manual_parameters.items():
        missing = [n for n in names if n not in manual.values]
        extra = [n for n in manual.values if n not in names]
        if missing or extra:
            if strict:
                problem = f"missing key {quote(missing[0])}" if missing else f"{quote(extra[0])} is not a learnable parameter of the plan"
                raise ScenarioError(f"{manual.where}: {problem} (the plan's parameters: {', '.join(names)})")
            continue
        sets[set_name] = frozen_array([manual.values[n] for n in names])
    return frozen_mapping(sets)


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


def planning_texts(task: PlannedTask) -> dict[str, str]:
    """The planning artefacts a run directory keeps: file name -> text."""
    return {
        "domain.pddl": task.domain_pddl,
        "problem.pddl": task.problem_pddl,
        "plan.txt": f"; goal: {task.goal}\n" + "\n".join(task.plan),
        "bt.txt": render(task.tree),
    }


__all__ = ["PlannedTask", "describe", "plan_task", "planning_texts"]
