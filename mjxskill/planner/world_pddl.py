"""World model -> PDDL: the domain (types, predicates, one action per skill) and the problem
(objects and initial facts of the world model, the user's goal) as PDDL text.

Names are lower-cased (PDDL is case-insensitive; planners print lower case). The goal accepts
SkiROS' namespaced form ``(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)`` as well as plain PDDL
``(at peg-1 boxwithhole-1)``, including ``(and ...)`` and ``(not ...)``; it is read with the
``pddl`` package and every predicate and object is checked against the world model.
"""

from __future__ import annotations

import difflib
import functools
import re
from typing import TYPE_CHECKING, Mapping

from pddl.logic.base import And, Not
from pddl.logic.predicates import Predicate
from pddl.parser.domain import DomainParser
from pddl.parser.problem import ProblemParser

from mjxskill.errors import GoalError, listing, quote

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario.schema import Scenario


@functools.cache
def _cached_parser(cls):
    return cls()


def _parse(cls, text: str):
    """Parses with one ``pddl`` parser per class: building its lark parser costs ~0.1 s, a
    parse of our small files milliseconds. The parser's transformer keeps tables from the
    previous text, so it is re-initialised (in place: lark holds it) before every parse."""
    parser = _cached_parser(cls)
    parser._transformer.__init__()
    return parser(text)


# A literal as written in the scenario files: (pred arg ...) or (not (pred arg ...)).
_ATOM = re.compile(r"^\(\s*([^\s()]+)((?:\s+[^\s()]+)*)\s*\)$")
_NEGATED = re.compile(r"^\(\s*not\s+(\(.*\))\s*\)$", re.IGNORECASE)
# SkiROS namespace prefixes such as "skiros:" in front of a name.
_NAMESPACE = re.compile(r"(?<![\w?:-])[A-Za-z_][\w]*:(?=[A-Za-z_])")


def parse_literal(text: str) -> tuple[bool, str, tuple[str, ...]] | None:
    """``"(not (at ?a ?b))"`` -> (False, "at", ("?a", "?b")); None if it is no literal."""
    text = text.strip()
    positive = True
    negated = _NEGATED.match(text)
    if negated:
        positive, text = False, negated.group(1)
    match = _ATOM.match(text)
    if not match:
        return None
    return positive, match.group(1).lower(), tuple(a.lower() for a in match.group(2).split())


def is_subtype(types: Mapping[str, str | None], child: str, ancestor: str) -> bool:
    """Whether PDDL type ``child`` is ``ancestor`` or derives from it."""
    seen = set()
    current: str | None = child
    while current is not None and current not in seen:
        if current == ancestor:
            return True
        seen.add(current)
        current = types.get(current)
    return False


def close_matches(name: str, choices) -> str:
    matches = difflib.get_close_matches(name, list(choices), n=3, cutoff=0.5)
    return f"; did you mean {listing(matches)}?" if matches else ""


def check_atom(
    predicate: str,
    args: tuple[str, ...],
    predicates: Mapping[str, tuple[str, ...]],
    types: Mapping[str, str | None],
    arg_types: Mapping[str, str],
    what: str = "object",
) -> str | None:
    """Why ``(predicate args...)`` is not a valid atom, or None if it is.

    arg_types: argument name (object or ?variable, lower case) -> its PDDL type.
    """
    if predicate not in predicates:
        return f"unknown predicate {quote(predicate)}{close_matches(predicate, predicates)} (known: {listing(predicates)})"
    expected = predicates[predicate]
    if len(args) != len(expected):
        return f"predicate {quote(predicate)} takes {len(expected)} arguments ({listing(expected)}), got {len(args)}"
    for arg, expected_type in zip(args, expected):
        if arg not in arg_types:
            return f"unknown {what} {quote(arg)} in ({predicate} {' '.join(args)}){close_matches(arg, arg_types)}"
        if not is_subtype(types, arg_types[arg], expected_type):
            return f"{quote(arg)} is a {arg_types[arg]}, but ({predicate} ...) wants a {expected_type} there"
    return None


def object_types(scn: "Scenario") -> dict[str, str]:
    """PDDL object name -> PDDL type, robot included."""
    table = {obj.pddl_name: obj.type for obj in scn.objects.values()}
    table[scn.robot.pddl_name] = scn.robot.type
    return table


# -- goal -------------------------------------------------------------------------------------
def _check_parentheses(goal: str) -> None:
    depth = 0
    for column, char in enumerate(goal, start=1):
        if char == "(":
            depth += 1
        elif char == ")":
            depth -= 1
            if depth < 0:
                raise GoalError(f"goal {quote(goal)}: unbalanced parentheses: unexpected ')' at column {column}")
    if depth > 0:
        raise GoalError(f"goal {quote(goal)}: unbalanced parentheses: {depth} '(' not closed")


def goal_literals(scn: "Scenario", goal: str) -> tuple[tuple[bool, str, tuple[str, ...]], ...]:
    """The goal as checked literals (positive, predicate, objects), all names lower case.

    Raises GoalError for an empty or unbalanced goal, PDDL the ``pddl`` package cannot read,
    formulas beyond conjunctions of literals, and unknown predicates or objects (with close
    matches).
    """
    if not isinstance(goal, str) or not goal.strip():
        raise GoalError(f"empty goal {quote(goal)}: write one like (at peg-1 boxwithhole-1)")
    _check_parentheses(goal)
    plain = _NAMESPACE.sub("", goal.strip()).lower()
    if not plain.startswith("("):
        raise GoalError(f"goal {quote(goal)}: a goal is a parenthesised PDDL formula, e.g. (at peg-1 boxwithhole-1)")
    try:
        problem = _parse(ProblemParser, f"(define (problem goal) (:domain {scn.name}) (:init) (:goal {plain}))")
    except Exception as err:  # lark's errors: report the first line, which names the token
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise GoalError(f"goal {quote(goal)} is not valid PDDL: {first}") from None

    literals = []

    def visit(formula, positive=True):
        if isinstance(formula, And) and positive:
            for operand in formula.operands:
                visit(operand)
        elif isinstance(formula, Not) and positive:
            visit(formula.argument, positive=False)
        elif isinstance(formula, Predicate):
            literals.append((positive, formula.name.lower(), tuple(t.name.lower() for t in formula.terms)))
        else:
            raise GoalError(
                f"goal {quote(goal)}: only conjunctions of atoms and negated atoms are supported, got {formula}"
            )

    visit(problem.goal)
    if not literals:
        raise GoalError(f"goal {quote(goal)} is empty")
    types = object_types(scn)
    for _, predicate, args in literals:
        problem_text = check_atom(predicate, args, scn.predicates, scn.types, types)
        if problem_text:
            raise GoalError(f"goal {quote(goal)}: {problem_text}")
    return tuple(literals)


def _literal_text(positive: bool, predicate: str, args: tuple[str, ...]) -> str:
    atom = f"({' '.join((predicate, *args))})"
    return atom if positive else f"(not {atom})"


def goal_pddl(scn: "Scenario", goal: str) -> str:
    """The goal as plain PDDL, e.g. ``(and (at peg-1 boxwithhole-1))``."""
    return "(and " + " ".join(_literal_text(*lit) for lit in goal_literals(scn, goal)) + ")"


# -- domain and problem -------------------------------------------------------------------------
def _needs_negative_preconditions(scn: "Scenario") -> bool:
    for skill in scn.skills.values():
        for condition in (*skill.preconditions, *skill.holdconditions):
            literal = parse_literal(condition)
            if literal is not None and not literal[0]:
                return True
    return False


def domain_pddl(scn: "Scenario", negative_goal: bool = False) -> str:
    """The PDDL domain: types, predicates and one action per skill of the library."""
    requirements = [":strips", ":typing"]
    if negative_goal or _needs_negative_preconditions(scn):
        requirements.append(":negative-preconditions")
    by_parent: dict[str, list[str]] = {}
    for name, parent in scn.types.items():
        by_parent.setdefault(parent or "object", []).append(name)
    type_lines = " ".join(f"{' '.join(children)} - {parent}" for parent, children in by_parent.items())
    predicate_lines = "\n    ".join(
        f"({name}{''.join(f' ?a{i} - {t}' for i, t in enumerate(arg_types))})"
        for name, arg_types in scn.predicates.items()
    )
    actions = []
    for skill in scn.skills.values():
        parameters = " ".join(f"?{p.name.lower()} - {p.type}" for p in skill.arguments)
        preconditions = " ".join(c.lower() for c in (*skill.preconditions, *skill.holdconditions))
        effects = " ".join(c.lower() for c in skill.postconditions)
        actions.append(
            f"  (:action {skill.pddl_name}\n"
            f"    :parameters ({parameters})\n"
            f"    :precondition (and {preconditions})\n"
            f"    :effect (and {effects}))"
        )
    text = (
        f"(define (domain {scn.name})\n"
        f"  (:requirements {' '.join(requirements)})\n"
        f"  (:types {type_lines})\n"
        f"  (:predicates\n    {predicate_lines})\n" + "\n".join(actions) + ")\n"
    )
    _parse(DomainParser, text)  # the generated text must be readable by a standard PDDL reader
    return text


def problem_pddl(scn: "Scenario", goal: str) -> str:
    """The PDDL problem: objects and initial facts of the world model, and ``goal``."""
    goal_text = goal_pddl(scn, goal)
    objects = " ".join(f"{name} - {type_}" for name, type_ in object_types(scn).items())
    facts = []
    for relation in (*scn.robot.relations, *(r for o in scn.objects.values() for r in o.relations)):
        literal = parse_literal(relation)
        assert literal is not None  # the loader keeps only the facts it parsed (scenario.load._relations)
        positive, predicate, args = literal
        facts.append(_literal_text(positive, predicate, args))
    init = "\n    ".join(dict.fromkeys(facts))  # a fact listed by two objects once
    text = (
        f"(define (problem {scn.name}-task)\n"
        f"  (:domain {scn.name})\n"
        f"  (:objects {objects})\n"
        f"  (:init\n    {init})\n"
        f"  (:goal {goal_text}))\n"
    )
    _parse(ProblemParser, text)
    return text
