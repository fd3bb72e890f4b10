"""Lifted task -> ground task: operators over ground facts, statics pruned, equality resolved.

A ground fact is its PDDL text, e.g. ``"(at b1 rooma)"``; a state is a frozenset of the facts
that hold, counting only fluent facts (those some action adds or deletes): static facts never
change, so they are checked once here and left out of states and operators.
"""

from __future__ import annotations

from typing import Iterator, NamedTuple

from mjxskill.planner.errors import Unsolvable
from mjxskill.planner.parse import ActionSchema, Atom, LiftedTask


class Operator(NamedTuple):
    """A ground action. Applying it removes ``delete`` and then adds ``add`` (so a fact in both
    ends up true)."""

    name: str  # "(pick b1 rooma left)"
    pre_pos: frozenset[str]
    pre_neg: frozenset[str]
    add: frozenset[str]
    delete: frozenset[str]


class GroundTask(NamedTuple):
    facts: frozenset[str]  # every fluent fact that can become true
    init: frozenset[str]
    goal_pos: frozenset[str]
    goal_neg: frozenset[str]
    operators: tuple[Operator, ...]  # in a fixed order: schema name, then objects sorted


def applicable(op: Operator, state: frozenset[str]) -> bool:
    return op.pre_pos <= state and state.isdisjoint(op.pre_neg)


def apply(op: Operator, state: frozenset[str]) -> frozenset[str]:
    return (state - op.delete) | op.add


def is_goal(task: GroundTask, state: frozenset[str]) -> bool:
    return task.goal_pos <= state and state.isdisjoint(task.goal_neg)


def fact(atom: Atom, binding: dict[str, str] | None = None) -> str:
    args = atom.args if binding is None else [binding.get(a, a) for a in atom.args]
    return "(" + " ".join([atom.predicate, *args]) + ")"


def ground(task: LiftedTask, prune_unreachable: bool = True) -> GroundTask:
    """Grounds ``task``; raises `Unsolvable` when a static goal literal is false.

    With ``prune_unreachable``, operators that are not reachable in the delete relaxation
    (negative preconditions ignored, so this over-approximates) are dropped: no plan can use them.
    """
    fluent_predicates = {a.predicate for s in task.actions for a in s.add + s.delete}
    static_init = frozenset(fact(a) for a in task.init if a.predicate not in fluent_predicates)
    init = frozenset(fact(a) for a in task.init if a.predicate in fluent_predicates)

    goal_pos: set[str] = set()
    goal_neg: set[str] = set()
    for literals, positive in ((task.goal.pos, True), (task.goal.neg, False)):
        for atom in literals:
            text = fact(atom)
            if atom.predicate in fluent_predicates:
                (goal_pos if positive else goal_neg).add(text)
            elif (text in static_init) != positive:
                raise Unsolvable(f"goal literal {'' if positive else 'not '}{text} concerns a "
                                 "predicate no action changes and is false initially")
    for (a, b), want in [(p, True) for p in task.goal.equal] + \
                        [(p, False) for p in task.goal.not_equal]:
        if (a == b) != want:
            raise Unsolvable(f"goal requires {a} {'=' if want else '!='} {b}")

    operators = []
    for schema in task.actions:
        for binding in _bindings(schema, task.objects, static_init, fluent_predicates):
            pre_pos = frozenset(fact(a, binding) for a in schema.pre.pos
                                if a.predicate in fluent_predicates)
            pre_neg = frozenset(fact(a, binding) for a in schema.pre.neg
                                if a.predicate in fluent_predicates)
            if not pre_pos.isdisjoint(pre_neg):
                continue  # contradictory precondition: never applicable
            name = "(" + " ".join([schema.name] + [binding[v] for v, _ in schema.parameters]) + ")"
            operators.append(Operator(name, pre_pos, pre_neg,
                                      frozenset(fact(a, binding) for a in schema.add),
                                      frozenset(fact(a, binding) for a in schema.delete)))

    if prune_unreachable:
        operators, reachable = _relaxed_reachable(operators, init)
    else:
        reachable = set(init).union(*(op.add for op in operators))
    facts = frozenset(reachable)
    return GroundTask(facts, init, frozenset(goal_pos), frozenset(goal_neg), tuple(operators))


def _bindings(schema: ActionSchema, objects: dict[str, frozenset[str]],
              static_init: frozenset[str], fluent_predicates: set[str]) -> Iterator[dict]:
    """Parameter assignments that satisfy the schema's static and equality preconditions.

    Backtracking over parameters in order; each static literal and (in)equality is checked as
    soon as its last variable is bound, which prunes most of the cross product early.
    """
    variables = [v for v, _ in schema.parameters]
    position = {v: i for i, v in enumerate(variables)}
    candidates = [[o for o in sorted(objects) if objects[o] & types]
                  for _, types in schema.parameters]

    def ready_at(args) -> int:
        # index of the parameter whose binding makes the check decidable (-1: decidable now)
        return max((position[a] for a in args if a.startswith("?")), default=-1)

    # checks[i]: decidable once parameter i is bound; checks[-1]: variable-free ones
    checks: list[list] = [[] for _ in range(len(variables) + 1)]
    literals = [(a, True) for a in schema.pre.pos] + [(a, False) for a in schema.pre.neg]
    for atom, positive in literals:
        if atom.predicate not in fluent_predicates:
            checks[ready_at(atom.args)].append(("fact", atom, positive))
    pairs = [(p, True) for p in schema.pre.equal] + [(p, False) for p in schema.pre.not_equal]
    for pair, want in pairs:
        checks[ready_at(pair)].append(("eq", pair, want))

    def holds(check, binding) -> bool:
        kind, what, want = check
        if kind == "fact":
            return (fact(what, binding) in static_init) == want
        a, b = (binding.get(t, t) for t in what)
        return (a == b) == want

    binding: dict[str, str] = {}
    if not all(holds(c, binding) for c in checks[-1]):  # -1 holds the variable-free checks
        return

    def extend(i: int) -> Iterator[dict]:
        if i == len(variables):
            yield dict(binding)
            return
        for obj in candidates[i]:
            binding[variables[i]] = obj
            if all(holds(c, binding) for c in checks[i]):
                yield from extend(i + 1)
        binding.pop(variables[i], None)

    yield from extend(0)


def _relaxed_reachable(operators: list[Operator], init: frozenset[str]):
    """Operators (in their original order) reachable from ``init`` ignoring deletes and negative
    preconditions, and the facts they can reach."""
    reached = set(init)
    waiting: dict[str, list[int]] = {}
    missing = []
    frontier = []
    for i, op in enumerate(operators):
        missing.append(len(op.pre_pos))
        for f in op.pre_pos:
            waiting.setdefault(f, []).append(i)
        if not op.pre_pos:
            frontier.append(i)
    usable = set()
    queue = list(init)
    while frontier or queue:
        while frontier:
            i = frontier.pop()
            usable.add(i)
            for f in operators[i].add:
                if f not in reached:
                    reached.add(f)
                    queue.append(f)
        if queue:
            f = queue.pop()
            for i in waiting.get(f, ()):
                missing[i] -= 1
                if missing[i] == 0:
                    frontier.append(i)
    return [op for i, op in enumerate(operators) if i in usable], reached
