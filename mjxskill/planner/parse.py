"""PDDL text -> lifted task, for STRIPS with :typing, :negative-preconditions and :equality.

The `pddl` package (lark based) does the parsing; this module turns its object model into small
tuples the grounder can use, and checks what `pddl` lets through (unknown predicates, wrong
arity, undeclared variables, unknown objects, requirements we do not support). Every error is a
`PDDLError` that names the line and column of the offending text.
"""

from __future__ import annotations

import threading
from typing import NamedTuple

import lark
from pddl.exceptions import PDDLError as PDDLLibraryError
from pddl.logic.base import And, Not, Or
from pddl.logic.predicates import EqualTo, Predicate
from pddl.logic.terms import Variable
from pddl.parser.domain import DomainParser
from pddl.parser.problem import ProblemParser

from mjxskill.errors import quote
from mjxskill.planner.errors import PDDLError
from mjxskill.planner.source import Source

SUPPORTED_REQUIREMENTS = frozenset({":strips", ":typing", ":negative-preconditions", ":equality"})
OBJECT = "object"


class Atom(NamedTuple):
    """A predicate applied to terms; a term starting with ``?`` is a variable, else an object."""

    predicate: str
    args: tuple[str, ...]


class Condition(NamedTuple):
    """A conjunction of literals (what a precondition or goal may be)."""

    pos: tuple[Atom, ...]
    neg: tuple[Atom, ...]
    equal: tuple[tuple[str, str], ...]  # (= a b) pairs
    not_equal: tuple[tuple[str, str], ...]  # (not (= a b)) pairs


class ActionSchema(NamedTuple):
    name: str
    parameters: tuple[tuple[str, frozenset[str]], ...]  # (?var, types it may have: `either`)
    pre: Condition
    add: tuple[Atom, ...]
    delete: tuple[Atom, ...]


class LiftedTask(NamedTuple):
    """A parsed and checked planning task; all names lower case.

    ``objects`` maps every object and domain constant to the set of types it belongs to (its
    declared type, all ancestors, and ``object``). ``actions`` are sorted by name so that
    grounding, and hence the plan, does not depend on set iteration order.
    """

    domain_name: str
    problem_name: str
    objects: dict[str, frozenset[str]]
    predicates: dict[str, int]  # name -> arity
    actions: tuple[ActionSchema, ...]
    init: frozenset[Atom]
    goal: Condition


# Building pddl's lark parser costs ~0.1 s, so one of each is kept; its transformer carries state
# between calls (and is left inconsistent by a failed parse), so it is re-initialised before every
# use, under a lock.
_PARSERS: dict[type, DomainParser | ProblemParser] = {}
_PARSER_LOCK = threading.Lock()


def _run_pddl_parser(parser_cls, src: Source):
    with _PARSER_LOCK:
        parser = _PARSERS.get(parser_cls)
        if parser is None:
            parser = _PARSERS[parser_cls] = parser_cls()
        parser._transformer.__init__()
        # PDDL is case-insensitive but pddl's grammar only knows lower-case keywords; lower()
        # keeps offsets (checked) so positions still match the user's text.
        lowered = src.text.lower()
        text = lowered if len(lowered) == len(src.text) else src.text
        try:
            return parser(text)
        except lark.exceptions.UnexpectedInput as error:
            raise _syntax_error(src, error) from None
        except PDDLError:
            raise
        except Exception as error:  # pddl's semantic errors carry no position: find it
            raise _semantic_error(src, error) from None


_END = {"$END", "<END-OF-FILE>"}  # lark's names for the end of the text
_TERMINALS = {"LPAR": "'('", "RPAR": "')'", "$END": "end of input",
              "<END-OF-FILE>": "end of input", "NAME": "a name", "VARIABLE": "a variable",
              "TYPE_SEP": "'-'", "NUMBER": "a number", "QMARK": "a variable"}


def _describe_terminals(names) -> str:
    readable = sorted({_TERMINALS.get(n, n.lower().replace("_", "-")) for n in names})
    return " or ".join(readable)


def _syntax_error(src: Source, error: lark.exceptions.UnexpectedInput) -> PDDLError:
    line, column = getattr(error, "line", None), getattr(error, "column", None)
    if line is None or line < 0:
        line, column = src.line_column(len(src.text))
    if isinstance(error, lark.exceptions.UnexpectedToken):
        if error.token.type in _END:
            what = "unexpected end of input (unbalanced parentheses?)"
        elif error.token.type == "RPAR" and set(error.expected) <= _END:
            what = "unexpected ')' after the end of the definition (unbalanced parentheses?)"
        else:
            what = f"unexpected {quote(error.token.value)}"
        if error.expected:
            what += f"; expected {_describe_terminals(error.expected)}"
    elif isinstance(error, lark.exceptions.UnexpectedCharacters):
        what = f"unexpected character {error.char!r}"
        if error.allowed:
            what += f"; expected {_describe_terminals(error.allowed)}"
    else:
        what = "unexpected end of input (unbalanced parentheses?)"
    return PDDLError(src.kind, line, column, what)


# The construct that needs each requirement, to point at it when pddl reports one missing.
_REQUIREMENT_KEYWORDS = {
    ":equality": ("=",), ":disjunctive-preconditions": ("or", "imply"),
    ":universal-preconditions": ("forall",), ":existential-preconditions": ("exists",),
    ":quantified-preconditions": ("forall", "exists"), ":typing": ("either", ":types"),
    ":non-deterministic": ("oneof",), ":numeric-fluents": ("increase", "decrease", "assign"),
    ":action-costs": ("total-cost", "increase"),
}


def _semantic_error(src: Source, error: Exception) -> PDDLError:
    message = str(error) or type(error).__name__
    requirement = getattr(error, "requirement", None)
    if requirement is not None:
        # e.g. (= ...) without :equality: pddl names the requirement but not the place
        if str(requirement) in SUPPORTED_REQUIREMENTS:
            what = f"uses {requirement} but :requirements does not declare it"
        else:
            what = f"uses {requirement}, which is not supported"
        keywords = _REQUIREMENT_KEYWORDS.get(str(requirement), ())
        return src.error(what, src.locate([([k], True) for k in keywords]))
    if not isinstance(error, (lark.exceptions.LarkError, PDDLLibraryError)):
        # a crash inside pddl's transformer (e.g. TypeError on some malformed actions)
        return src.error(f"malformed PDDL: the pddl parser failed with "
                         f"{type(error).__name__}: {message}", None)
    # pddl quotes the offending names, e.g. "Constant 'kitchen' not defined."
    names = [part for i, part in enumerate(message.split("'")) if i % 2 == 1]
    offset = src.locate([([n], False) for n in names])
    if message.startswith("Constant '") and message.endswith("' not defined."):
        message = f"unknown constant {quote(names[0])} (objects in a domain must be in :constants)"
    return src.error(message.rstrip("."), offset)


def parse(domain_text: str, problem_text: str) -> LiftedTask:
    """Parses and checks a domain and problem given as PDDL text."""
    if not isinstance(domain_text, str) or not isinstance(problem_text, str):
        raise TypeError("parse() takes the domain and problem as PDDL text (str), got "
                        f"{type(domain_text).__name__} and {type(problem_text).__name__}")
    dsrc, psrc = Source("domain", domain_text), Source("problem", problem_text)
    domain = _run_pddl_parser(DomainParser, dsrc)
    problem = _run_pddl_parser(ProblemParser, psrc)

    _check_requirements(dsrc, domain.requirements)
    _check_requirements(psrc, problem.requirements)
    if str(problem.domain_name).lower() != str(domain.name).lower():
        raise psrc.error(f"problem is for domain {quote(str(problem.domain_name))} but the domain is "
                         f"{quote(str(domain.name))}", psrc.locate([([":domain"], True)]))

    ancestors = _type_ancestors(dsrc, domain.types)
    objects: dict[str, frozenset[str]] = {}
    for src, declared in ((dsrc, domain.constants), (psrc, problem.objects)):
        for obj in sorted(declared, key=lambda o: str(o.name)):
            types = _declared_types(src, obj.type_tags, ancestors, f"object {obj.name}")
            objects[str(obj.name).lower()] = frozenset().union(*(ancestors[t] for t in types))

    predicates = {}
    for pred in domain.predicates:
        for term in pred.terms:
            _declared_types(dsrc, term.type_tags, ancestors, f"predicate {pred.name}")
        predicates[str(pred.name).lower()] = len(pred.terms)

    negation_declared = ":negative-preconditions" in {str(r) for r in domain.requirements}
    actions = tuple(sorted((_action(dsrc, a, predicates, objects, ancestors, negation_declared)
                            for a in domain.actions), key=lambda a: a.name))

    init_span = psrc.section([":init"])
    init = []
    for fact in problem.init:
        if not isinstance(fact, Predicate):
            raise psrc.error(f"unsupported initial-state entry {fact} (only atoms; numeric "
                             "fluents are not supported)", psrc.locate([], init_span))
        init.append(_atom(psrc, fact, predicates, objects, (), init_span, "the initial state"))
    goal_span = psrc.section([":goal"])
    goal = _condition(psrc, problem.goal, predicates, objects, (), goal_span, "the goal",
                      negation_declared)
    return LiftedTask(str(domain.name).lower(), str(problem.name).lower(), objects, predicates,
                      actions, frozenset(init), goal)


def _check_requirements(src: Source, requirements) -> None:
    for requirement in sorted(str(r) for r in requirements):
        if requirement not in SUPPORTED_REQUIREMENTS:
            raise src.error(f"unsupported requirement {requirement} (supported: "
                            f"{', '.join(sorted(SUPPORTED_REQUIREMENTS))})",
                            src.locate([([requirement], False)]))


def _type_ancestors(src: Source, types) -> dict[str, frozenset[str]]:
    """Type -> itself and all its ancestors (always including ``object``)."""
    parent = {str(t).lower(): (str(p).lower() if p is not None else OBJECT)
              for t, p in types.items()}
    parent.pop(OBJECT, None)
    for p in list(parent.values()):
        parent.setdefault(p, OBJECT)
    parent.pop(OBJECT, None)
    ancestors = {OBJECT: frozenset({OBJECT})}
    for start in parent:
        chain, t = [], start
        while t != OBJECT:
            if t in chain:
                raise src.error(f"type hierarchy has a cycle through {quote(t)}",
                                src.locate([([t], False)], src.section([":types"])))
            chain.append(t)
            # a parent named but not declared itself (`a b - c`) is a child of `object`, as
            # in Fast Downward
            t = parent.get(t, OBJECT)
        ancestors[start] = frozenset(chain) | {OBJECT}
    return ancestors


def _declared_types(src: Source, type_tags, ancestors, where: str) -> frozenset[str]:
    types = frozenset(str(t).lower() for t in type_tags) or frozenset({OBJECT})
    for t in sorted(types):
        if t not in ancestors:
            raise src.error(f"unknown type {quote(t)} in {where}", src.locate([([t], False)]))
    return types


def _term(term) -> str:
    name = str(term.name).lower()
    return "?" + name if isinstance(term, Variable) else name


def _action(src: Source, action, predicates, objects, ancestors,
            negation_declared: bool) -> ActionSchema:
    name = str(action.name).lower()
    span = src.section([":action", name])
    params = []
    for var in action.parameters:
        types = _declared_types(src, var.type_tags, ancestors, f"action {name}")
        params.append(("?" + str(var.name).lower(), types))
    where = f"action {name}"
    variables = tuple(p for p, _ in params)
    if len(set(variables)) != len(variables):
        raise src.error(f"{where} declares a parameter twice", src.locate([], span))
    pre = _condition(src, action.precondition, predicates, objects, variables, span, where,
                     negation_declared)
    add: list[Atom] = []
    delete: list[Atom] = []
    effects = _conjuncts(action.effect)
    for effect in effects:
        target = add
        if isinstance(effect, Not):
            effect, target = effect.argument, delete
        if not isinstance(effect, Predicate):
            raise src.error(f"unsupported effect {effect} in {where} (only atoms and negated "
                            "atoms: conditional, quantified and numeric effects are not "
                            "supported)", src.locate([(_head(effect), True)], span))
        target.append(_atom(src, effect, predicates, objects, variables, span, where))
    return ActionSchema(name, tuple(params), pre, tuple(add), tuple(delete))


def _conjuncts(formula) -> list:
    """Flattens nested ``and``; an absent or empty formula (pddl gives ``Or()`` for ``()``) is
    the empty conjunction."""
    if formula is None or (isinstance(formula, Or) and not formula.operands):
        return []
    if isinstance(formula, And):
        return [c for operand in formula.operands for c in _conjuncts(operand)]
    return [formula]


def _head(formula) -> list[str]:
    """Best guess at the keyword that opens ``formula`` in the text, for error positions."""
    text = str(formula)
    return [text[1:].split(" ", 1)[0].rstrip(")")] if text.startswith("(") else [text]


def _condition(src, formula, predicates, objects, variables, span, where,
               negation_declared: bool) -> Condition:
    pos: list[Atom] = []
    neg: list[Atom] = []
    equal: list[tuple[str, str]] = []
    not_equal: list[tuple[str, str]] = []
    for literal in _conjuncts(formula):
        negated = isinstance(literal, Not)
        inner = literal.argument if negated else literal
        if isinstance(inner, EqualTo):
            here = src.locate([(["="], True)], span)
            pair = (_checked_term(src, inner.left, objects, variables, span, where, here),
                    _checked_term(src, inner.right, objects, variables, span, where, here))
            (not_equal if negated else equal).append(pair)
        elif isinstance(inner, Predicate):
            atom = _atom(src, inner, predicates, objects, variables, span, where)
            if negated and not negation_declared:
                raise src.error(f"negated atom (not {_format(atom)}) in {where} needs "
                                ":negative-preconditions in the domain's :requirements",
                                src.locate([(["not", "(" + atom.predicate, *atom.args], True),
                                            (["not"], True)], span))
            (neg if negated else pos).append(atom)
        else:
            raise src.error(f"unsupported condition {literal} in {where} (only conjunctions of "
                            "atoms, negated atoms and (= a b): disjunctions, implications, "
                            "quantifiers and numeric comparisons are not supported)",
                            src.locate([(_head(literal), True)], span))
    return Condition(tuple(pos), tuple(neg), tuple(equal), tuple(not_equal))


def _checked_term(src, term, objects, variables, span, where, offset=None) -> str:
    """The term's name, after checking it is a declared variable or object; errors point at
    ``offset`` (the enclosing atom) when given, else at the name itself."""
    name = _term(term)
    if name.startswith("?"):
        if name not in variables:
            raise src.error(f"undeclared variable {name} in {where}",
                            src.locate([([name], False)], span) if offset is None else offset)
    elif name not in objects:
        raise src.error(f"unknown object {quote(name)} in {where}",
                        src.locate([([name], False)], span) if offset is None else offset)
    return name


def _atom(src, predicate, predicates, objects, variables, span, where) -> Atom:
    name = str(predicate.name).lower()
    args = [_term(t) for t in predicate.terms]
    here = src.locate([([name] + args, True), ([name], True)], span)
    if name not in predicates:
        raise src.error(f"unknown predicate {quote(name)} in {where}", here)
    if len(args) != predicates[name]:
        raise src.error(f"predicate {quote(name)} takes {predicates[name]} argument(s) but "
                        f"{len(args)} are given in {where}", here)
    for term in predicate.terms:
        _checked_term(src, term, objects, variables, span, where, here)
    return Atom(name, tuple(args))


def _format(atom: Atom) -> str:
    return "(" + " ".join((atom.predicate,) + atom.args) + ")"
