"""A* over ground states, unit action costs, deterministic tie-breaking.

Ties on f = g + h are broken by smaller h (deeper nodes first), then by insertion order.
Successors are generated in the ground task's operator order, so the returned plan does not
depend on set iteration order or the Python hash seed.
"""

from __future__ import annotations

import heapq
import math
from typing import Callable

from mjxskill.planner.errors import Unsolvable
from mjxskill.planner.ground import GroundTask, Operator, is_goal


def successor_generator(task: GroundTask) -> Callable[[frozenset], list[int]]:
    """Returns ``state -> indices of applicable operators, ascending``.

    Each operator is filed under one of its positive preconditions (the smallest), so a state
    only looks at operators whose filing fact it contains, instead of all of them.
    """
    ops = task.operators
    filed: dict[str, list[int]] = {}
    unconditional = []
    for i, op in enumerate(ops):
        if op.pre_pos:
            filed.setdefault(min(op.pre_pos), []).append(i)
        else:
            unconditional.append(i)

    def applicable(state: frozenset) -> list[int]:
        found = [i for i in unconditional if state.isdisjoint(ops[i].pre_neg)]
        for f in state:
            for i in filed.get(f, ()):
                op = ops[i]
                if op.pre_pos <= state and state.isdisjoint(op.pre_neg):
                    found.append(i)
        found.sort()
        return found

    return applicable


def astar(task: GroundTask, heuristic: Callable[[frozenset], float],
          max_expansions: int | None = None) -> list[Operator]:
    """An optimal plan if ``heuristic`` is admissible; raises `Unsolvable` if there is none.

    States are re-opened when reached by a cheaper path, so optimality does not need a
    consistent heuristic. ``max_expansions`` (None: unlimited) bounds the work; exceeding it
    raises RuntimeError.
    """
    ops = task.operators
    successors = successor_generator(task)
    start = task.init
    h0 = heuristic(start)
    if h0 == math.inf:
        raise Unsolvable("the goal is unreachable even ignoring delete effects (h_max = inf)")
    best_g = {start: 0}
    parent: dict[frozenset, tuple[frozenset, int]] = {}
    tiebreak = 0
    frontier = [(h0, h0, tiebreak, 0, start)]
    expansions = 0
    while frontier:
        _, _, _, g, state = heapq.heappop(frontier)
        if g > best_g[state]:
            continue  # stale entry: a cheaper path to this state was queued later
        if is_goal(task, state):
            return _trace(state, parent, ops)
        expansions += 1
        if max_expansions is not None and expansions > max_expansions:
            raise RuntimeError(f"A* gave up after {max_expansions} expansions")
        for i in successors(state):
            op = ops[i]
            child = (state - op.delete) | op.add
            child_g = g + 1
            if child_g >= best_g.get(child, math.inf):
                continue
            h = heuristic(child)
            if h == math.inf:
                best_g[child] = -1  # dead end: never queue it again
                continue
            best_g[child] = child_g
            parent[child] = (state, i)
            tiebreak += 1
            heapq.heappush(frontier, (child_g + h, h, tiebreak, child_g, child))
    raise Unsolvable("search space exhausted: no plan reaches the goal")


def _trace(state, parent, ops) -> list[Operator]:
    plan = []
    while state in parent:
        state, i = parent[state]
        plan.append(ops[i])
    plan.reverse()
    return plan
