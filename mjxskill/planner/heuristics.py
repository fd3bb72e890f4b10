"""Admissible heuristics for unit-cost A*: blind and h_max.

Both ignore negative preconditions (a relaxation, so they stay admissible). A heuristic is made
for one ground task and maps a state to an estimate of the plan length still needed, or
``math.inf`` when the state provably cannot reach the goal.
"""

from __future__ import annotations

import math
from typing import Callable

from mjxskill.planner.ground import GroundTask

Heuristic = Callable[[frozenset], float]


def blind(task: GroundTask) -> Heuristic:
    """0 in goal states, 1 elsewhere (admissible for unit costs)."""
    goal_pos, goal_neg = task.goal_pos, task.goal_neg

    def h(state: frozenset) -> float:
        return 0 if goal_pos <= state and state.isdisjoint(goal_neg) else 1

    return h


def hmax(task: GroundTask) -> Heuristic:
    """h_max (Bonet and Geffner 2001) for unit costs.

    With unit costs h_max(s) is the first layer of the relaxed planning graph from ``s`` that
    contains every positive goal fact, so it is computed by a layered reachability sweep with
    per-operator counters of unreached preconditions, in time linear in the task size.
    A negative goal fact that holds in ``s`` and that no operator deletes makes ``s`` a dead end.
    """
    ops = task.operators
    pre_count = [len(op.pre_pos) for op in ops]
    add = [tuple(op.add) for op in ops]
    triggered_by: dict[str, list[int]] = {}
    for i, op in enumerate(ops):
        for f in op.pre_pos:
            triggered_by.setdefault(f, []).append(i)
    free_ops = [i for i, n in enumerate(pre_count) if n == 0]
    goal = task.goal_pos
    deletable = frozenset().union(*(op.delete for op in ops))
    stuck_neg_goals = task.goal_neg - deletable

    def h(state: frozenset) -> float:
        if not stuck_neg_goals.isdisjoint(state):
            return math.inf
        missing_goals = len(goal - state)
        if missing_goals == 0:
            return 0
        reached = set(state)
        missing = pre_count.copy()
        layer_ops = list(free_ops)
        for f in state:
            for i in triggered_by.get(f, ()):
                missing[i] -= 1
                if missing[i] == 0:
                    layer_ops.append(i)
        level = 0
        while layer_ops:
            level += 1
            new_facts = []
            for i in layer_ops:
                for f in add[i]:
                    if f not in reached:
                        reached.add(f)
                        new_facts.append(f)
                        if f in goal:
                            missing_goals -= 1
            if missing_goals == 0:
                return level
            layer_ops = []
            for f in new_facts:
                for i in triggered_by.get(f, ()):
                    missing[i] -= 1
                    if missing[i] == 0:
                        layer_ops.append(i)
        return math.inf

    return h


HEURISTICS = {"blind": blind, "hmax": hmax}
