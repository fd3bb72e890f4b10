"""Admissible heuristics for unit-cost A*: blind, h_max and LM-cut.

Both ignore negative preconditions (a relaxation, so they stay admissible). A heuristic is made
for one ground task and maps a state to an estimate of the plan length still needed, or
``math.inf`` when the state provably cannot reach the goal.
"""

from __future__ import annotations

import heapq
import math
from typing import Callable, NamedTuple

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


class _Relaxed(NamedTuple):
    """LM-cut's view of a ground task: facts and operators by index, negative preconditions
    dropped. Fact ``start`` is the precondition of operators without one; the last operator is
    the artificial goal operator (cost 0), which needs every goal fact and adds fact ``goal``."""

    fact_index: dict  # fact -> its index (not `index`: that is tuple's method)
    start: int
    goal: int
    n_facts: int
    pre: list  # per operator: its precondition fact indices
    add: list  # per operator: its add-effect fact indices
    pre_of: list  # per fact: the operators it is a precondition of
    achievers: list  # per fact: the operators that add it
    unit_costs: list  # per operator: 1.0, 0.0 for the goal operator


def _relaxed(task: GroundTask) -> _Relaxed:
    ops = task.operators
    facts = sorted(task.facts | task.goal_pos | frozenset().union(*(op.pre_pos for op in ops)))
    index = {f: i for i, f in enumerate(facts)}
    start, goal = len(facts), len(facts) + 1
    n_facts = goal + 1
    pre = [tuple(sorted(index[f] for f in op.pre_pos)) or (start,) for op in ops]
    add = [tuple(sorted(index[f] for f in op.add)) for op in ops]
    pre.append(tuple(sorted(index[f] for f in task.goal_pos)) or (start,))
    add.append((goal,))
    n_ops = len(pre)
    pre_of: list[list[int]] = [[] for _ in range(n_facts)]
    achievers: list[list[int]] = [[] for _ in range(n_facts)]
    for o in range(n_ops):
        for f in pre[o]:
            pre_of[f].append(o)
        for f in add[o]:
            achievers[f].append(o)
    return _Relaxed(index, start, goal, n_facts, pre, add, pre_of, achievers, [1.0] * (n_ops - 1) + [0.0])


def lmcut(task: GroundTask) -> Heuristic:
    """LM-cut (Helmert and Domshlak 2009): a sum of disjunctive action landmarks, >= h_max.

    Each round computes h_max under the current (reduced) action costs, builds the
    justification graph (every operator links its costliest precondition, its "pcf", to its
    add effects), and cuts it between the facts reachable from the state and the goal zone
    (facts that reach the goal through zero-cost operators); the cheapest cut operator's cost
    is added to the estimate and subtracted from every cut operator. An artificial fact
    ``start`` is the precondition of operators without one, and an artificial goal operator
    needs all goal facts.
    """
    r = _relaxed(task)
    goal_pos = task.goal_pos
    stuck_neg_goals = task.goal_neg - frozenset().union(*(op.delete for op in task.operators))

    def h(state: frozenset) -> float:
        if not stuck_neg_goals.isdisjoint(state):
            return math.inf
        if goal_pos <= state:
            return 0
        sources = sorted(r.fact_index[f] for f in state if f in r.fact_index) + [r.start]
        cost = r.unit_costs.copy()
        total = 0.0
        while True:
            value, pcf = _hmax_and_pcf(r, sources, cost)
            if value[r.goal] == math.inf:
                return math.inf
            if value[r.goal] == 0:
                return round(total)  # unit costs: landmark costs sum to an integer
            cut = _cut(r, sources, pcf, _goal_zone(r, cost, pcf))
            landmark_cost = min(cost[o] for o in cut)
            total += landmark_cost
            for o in cut:
                cost[o] -= landmark_cost

    return h


def _hmax_and_pcf(r: _Relaxed, sources: list[int], cost: list[float]):
    """h_max of every fact under ``cost`` (Dijkstra) and each operator's pcf: its precondition
    settled last, which has the largest h_max (ties: heap order); -1 for unreached operators."""
    value = [math.inf] * r.n_facts
    settled = [False] * r.n_facts
    missing = [len(p) for p in r.pre]
    pcf = [-1] * len(r.pre)
    queue = [(0.0, f) for f in sources]
    for f in sources:
        value[f] = 0.0
    heapq.heapify(queue)
    pre_of, add = r.pre_of, r.add
    while queue:
        v, f = heapq.heappop(queue)
        if settled[f]:
            continue
        settled[f] = True
        for o in pre_of[f]:
            missing[o] -= 1
            if missing[o] == 0:
                pcf[o] = f
                reached = v + cost[o]
                for a in add[o]:
                    if reached < value[a]:
                        value[a] = reached
                        heapq.heappush(queue, (reached, a))
    return value, pcf


def _goal_zone(r: _Relaxed, cost: list[float], pcf: list[int]) -> set[int]:
    """The facts that reach the goal through zero-cost justification edges."""
    zone = {r.goal}
    stack = [r.goal]
    while stack:
        f = stack.pop()
        for o in r.achievers[f]:
            if cost[o] == 0 and pcf[o] >= 0 and pcf[o] not in zone:
                zone.add(pcf[o])
                stack.append(pcf[o])
    return zone


def _cut(r: _Relaxed, sources: list[int], pcf: list[int], zone: set[int]) -> set[int]:
    """The landmark: every operator from a fact reachable from ``sources`` without entering the
    goal ``zone`` (through justification edges) into the zone."""
    by_pcf: dict[int, list[int]] = {}
    for o in range(len(pcf)):
        if pcf[o] >= 0:
            by_pcf.setdefault(pcf[o], []).append(o)
    seen = set(sources)
    stack = list(sources)
    cut = set()
    while stack:
        f = stack.pop()
        for o in by_pcf.get(f, ()):
            for a in r.add[o]:
                if a in zone:
                    cut.add(o)
                elif a not in seen:
                    seen.add(a)
                    stack.append(a)
    return cut


HEURISTICS = {"blind": blind, "hmax": hmax, "lmcut": lmcut}
