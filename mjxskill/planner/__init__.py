"""Classical planner: optimal plans for STRIPS PDDL with typing, negative preconditions and
equality.

Stages, one module each (as in pyperplan): `parse` (PDDL text -> checked lifted task, via the
`pddl` package) -> `ground` (operators over ground facts) -> `search` (A*) with `heuristics`
(h_max). `solve` runs them all; `validate` checks a plan by applying it.
"""

from __future__ import annotations

from mjxskill.errors import quote
from mjxskill.planner.errors import PDDLError, Unsolvable
from mjxskill.planner.ground import GroundTask, Operator, apply, applicable, ground, is_goal
from mjxskill.planner.heuristics import HEURISTICS
from mjxskill.planner.parse import LiftedTask, parse
from mjxskill.planner.search import astar

__all__ = ["PDDLError", "Unsolvable", "solve", "validate", "parse", "ground", "astar",
           "LiftedTask", "GroundTask", "Operator"]


def solve(domain: str, problem: str, heuristic: str = "hmax",
          max_expansions: int | None = None) -> list[str]:
    """A plan with the fewest actions, as ground actions ``"(name arg ...)"`` in lower case.

    Args:
      domain, problem: PDDL text (not file names).
      heuristic: ``"hmax"`` (default), ``"lmcut"`` (more informed, slower per state on small
        tasks) or ``"blind"``; all admissible, so the plan is optimal.
      max_expansions: optional bound on A* expansions (RuntimeError when exceeded).

    Raises:
      PDDLError: malformed or unsupported PDDL (the message gives line and column).
      Unsolvable: no plan exists.
    """
    if heuristic not in HEURISTICS:
        raise ValueError(f"unknown heuristic {quote(heuristic)}; choose from {sorted(HEURISTICS)}")
    task = ground(parse(domain, problem))
    plan = astar(task, HEURISTICS[heuristic](task), max_expansions)
    return [op.name for op in plan]


def validate(domain: str, problem: str, plan: list[str]) -> bool:
    """Whether applying ``plan`` (ground actions ``"(name arg ...)"``, any case and spacing)
    from the initial state is possible step by step and ends in a goal state.

    Raises PDDLError for malformed PDDL; a plan step that names no ground action of the task
    (unknown action or objects, wrong arity, wrong types) makes the plan invalid.
    """
    try:
        task = ground(parse(domain, problem), prune_unreachable=False)
    except Unsolvable:
        return False
    by_name = {op.name: op for op in task.operators}
    state = task.init
    for step in plan:
        op = by_name.get(_normalize(step))
        if op is None or not applicable(op, state):
            return False
        state = apply(op, state)
    return is_goal(task, state)


def _normalize(step: str) -> str:
    words = str(step).strip().strip("()").lower().split()
    return "(" + " ".join(words) + ")"
