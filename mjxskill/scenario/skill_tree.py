"""A skill's ``tree`` in the YAML: read and checked into a template (``mjxskill.ebt.template``).

A node is a mapping with one kind key:

* processors ``sequence`` (``->``), ``serial_star`` (``->*``), ``selector`` (``?``),
  ``selector_star`` (``?*``), ``parallel`` (``||FF``), ``parallel_fs`` (``||FS``): the value is
  the node's name; ``children:`` a non-empty list of nodes;
* decorators ``inverter``, ``force_success``, ``repeat``, ``retry``, ``timeout``: the value is the
  name; ``child:`` one node; ``count:`` n (repeat, retry; timeout: BT ticks);
* leaves ``action``: the value is the leaf's name; ``primitive:`` one of
  ``mjxskill.ebt.primitives.PRIMITIVES``; ``args:`` its inputs (``INPUTS``), each a number, a
  text (a choice), a list, ``$parameter``, ``$argument.attribute[.x|.y|.z]`` or a sum such as
  ``$push_height - $workpiece.position.z``.

``$label`` in a name is the skill's label in the plan. Everything is checked here, so that a bad
template is a ``ScenarioError`` naming the file, the key and the line: an unknown kind,
primitive or input, a reference to no parameter of the skill, an attribute of something that is
no plan argument, a value of the wrong kind, a learnable parameter where the leaf cannot read
one at run time, a required input missing, a learnable parameter the tree never reads.
"""

from __future__ import annotations

import re

from mjxskill.errors import listing, quote
from mjxskill.ebt.nodes import Kind
from mjxskill.ebt.primitives import INPUTS, PRIMITIVES, REQUIRED
from mjxskill.ebt.template import COMPONENTS, OBJECT_ATTRIBUTES, LeafTemplate, NodeTemplate, Ref, Sum, references
from mjxskill.scenario.fields import Field
from mjxskill.scenario.domain import PARAMETER

PROCESSORS = {"sequence": Kind.SEQUENCE, "serial_star": Kind.SERIAL_STAR, "selector": Kind.SELECTOR,
              "selector_star": Kind.SELECTOR_STAR, "parallel": Kind.PARALLEL, "parallel_fs": Kind.PARALLEL_FS}
DECORATORS = {"inverter": Kind.INVERTER, "force_success": Kind.FORCE_SUCCESS, "repeat": Kind.REPEAT,
              "retry": Kind.RETRY, "timeout": Kind.TIMEOUT}
COUNTED = (Kind.REPEAT, Kind.RETRY, Kind.TIMEOUT)
NODE_KINDS = (*PROCESSORS, *DECORATORS, "action")

_REF = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)((?:\.[A-Za-z_][A-Za-z0-9_]*)*)")
_NUMBER = re.compile(r"[0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?")


def read_tree(field: Field, parameters) -> NodeTemplate | LeafTemplate:
    """The template in ``field`` for a skill with ``parameters`` (name -> SkillParameter);
    raises ScenarioError for anything the checks above refuse."""
    template = _node(field, parameters)
    used = {ref.name for ref in references(template)}
    for p in parameters.values():
        if p.learnable and p.name not in used:
            field.fail(f"the learnable parameter {quote(p.name)} is not read by the tree: the optimizer would search a "
                       f"value that changes nothing (read it in a leaf's args as ${p.name}, or set learnable: false)")
    return template


def _node(field: Field, parameters):
    if not field.node.tag.endswith(":map"):
        field.fail(f"a tree node is a mapping with one of {listing(NODE_KINDS)}")
    keys = [key for key, _ in field.items()]
    kinds = [key for key in keys if key in NODE_KINDS]
    if len(kinds) != 1:
        what = f"both {quote(kinds[0])} and {quote(kinds[1])}" if kinds else f"none of them (keys: {listing(keys)})"
        field.fail(f"a tree node has exactly one of {listing(NODE_KINDS)}; this one has {what}")
    kind = kinds[0]
    if kind == "action":
        return _leaf(field, parameters)
    if kind in PROCESSORS:
        f = field.mapping(required=(kind, "children"))
        children = f["children"].seq()
        if not children:
            f["children"].fail(f"a {kind} needs at least one child")
        return NodeTemplate(PROCESSORS[kind], _name(f[kind]), tuple(_node(c, parameters) for c in children))
    counted = DECORATORS[kind] in COUNTED
    f = field.mapping(required=(kind, "child", *(("count",) if counted else ())))
    count = f["count"].integer(minimum=1) if counted else 0
    return NodeTemplate(DECORATORS[kind], _name(f[kind]), (_node(f["child"], parameters),), count)


def _name(field: Field) -> str:
    name = field.string()
    for match in re.finditer(r"\$[A-Za-z_]\w*", name):
        if match.group(0) != "$label":
            field.fail(f"a name may use $label (the skill's label in the plan), not {match.group(0)}")
    return name


def _leaf(field: Field, parameters) -> LeafTemplate:
    f = field.mapping(required=("action", "primitive"), optional=("args",))
    primitive = f["primitive"].string()
    if primitive not in PRIMITIVES:
        f["primitive"].fail(f"unknown primitive {quote(primitive)} (primitives: {listing(PRIMITIVES)})")
    signature = INPUTS[primitive]
    given = f["args"].items() if "args" in f else []
    inputs = []
    for name, value in given:
        if name not in signature:
            value.fail(f"{primitive} has no input {quote(name)} (inputs: {listing(signature) or 'none'})")
        inputs.append((name, _input(value, signature[name], parameters)))
    for name, spec in signature.items():
        if spec.default is REQUIRED and name not in dict(given):
            (f["args"] if "args" in f else field).fail(f"{primitive} needs the input {quote(name)} ({spec.kind})")
    return LeafTemplate(_name(f["action"]), primitive, tuple(inputs))


def _input(field: Field, spec, parameters):
    """One input's value, checked against the input's kind."""
    kind = spec.kind
    if kind == "object":
        ref = _ref_text(field, parameters)
        if ref.path or not parameters[ref.name].plan:
            field.fail(f"expected a plan argument naming an object, like $target; got {ref}")
        return ref
    if kind == "choice":
        value = field.string()
        if value not in spec.choices:
            field.fail(f"{quote(value)} is not one of {listing(spec.choices)}")
        return value
    if kind == "number":
        value = _number(field, parameters, learnable_ok=spec.learnable)
        return value
    length = int(kind[-1])
    if field.node.tag.endswith(":seq"):
        items = field.seq()
        if len(items) != length:
            field.fail(f"expected {length} values, got {len(items)}")
        return tuple(_number(item, parameters, learnable_ok=False) for item in items)
    ref = _ref_text(field, parameters)
    found = _length(ref, parameters, field)
    if found != length:
        field.fail(f"{ref} is {'a number' if found == 0 else f'{found} values'}; expected {length} values")
    return ref


def _ref_text(field: Field, parameters) -> Ref:
    text = field.string()
    match = _REF.fullmatch(text.strip())
    if not match:
        field.fail(f"expected a reference like $threshold or $target.position, got {quote(text)}")
    return _reference(match, parameters, field)


def _reference(match, parameters, field: Field) -> Ref:
    name, path = match.group(1), tuple(p for p in match.group(2).split(".") if p)
    if name not in parameters:
        field.fail(f"${name} names no parameter of the skill (parameters: {listing(parameters)})")
    p = parameters[name]
    if path and not p.plan:
        field.fail(f"${name} is a {p.type}: only a plan argument (an object) has attributes like .position")
    if path:
        if path[0] not in OBJECT_ATTRIBUTES:
            field.fail(f"an object has no attribute {quote(path[0])} (attributes: {listing(OBJECT_ATTRIBUTES)})")
        if len(path) > 2 or (len(path) == 2 and path[1] not in COMPONENTS):
            field.fail(f"after .{path[0]} comes at most one of .x .y .z; got {'$' + match.group(0)[1:]}")
    return Ref(name, path)


def _length(ref: Ref, parameters, field: Field) -> int:
    """0 for a number, else the vector's length (an object's size: 3, checked when expanded)."""
    p = parameters[ref.name]
    if not ref.path:
        if p.plan:
            field.fail(f"{ref} names an object; expected a value (an attribute like {ref}.position)")
        return 0 if p.type == "float" else len(p.default)
    return 0 if len(ref.path) == 2 else (OBJECT_ATTRIBUTES[ref.path[0]] or 3)


def _number(field: Field, parameters, learnable_ok: bool):
    """A number: a literal, a reference to a number, or a sum of numbers and references."""
    if not field.node.tag.endswith(":str"):
        return field.number(PARAMETER)
    text = field.string().strip()
    terms: list[tuple[int, float | Ref]] = []
    sign, pos, expect_term = 1, 0, True
    while pos < len(text):
        if text[pos].isspace():
            pos += 1
        elif text[pos] in "+-":
            sign = -sign if text[pos] == "-" else sign
            expect_term, pos = True, pos + 1
        elif not expect_term:
            field.fail(f"expected + or - at {quote(text[pos:])} in {quote(text)}")
        elif (match := _REF.match(text, pos)) is not None:
            ref = _reference(match, parameters, field)
            if _length(ref, parameters, field) != 0:
                field.fail(f"{ref} is a vector; expected a number (a component like {ref}.z)")
            terms.append((sign, ref))
            sign, expect_term, pos = 1, False, match.end()
        elif (match := _NUMBER.match(text, pos)) is not None:
            terms.append((sign, float(match.group(0))))
            sign, expect_term, pos = 1, False, match.end()
        else:
            field.fail(f"expected a number or a reference like $threshold at {quote(text[pos:])} in {quote(text)}")
    if not terms or expect_term:
        field.fail(f"{quote(text)} is not a number, a reference or a sum of them")
    learnable = [t for _, t in terms if isinstance(t, Ref) and not t.path and parameters[t.name].learnable]
    if learnable and (not learnable_ok or len(terms) > 1 or terms[0][0] < 0):
        why = ("this input is fixed when the tree is built" if not learnable_ok else
               "a learnable parameter is read at run time, so it stands alone, not in a sum or negated")
        field.fail(f"{learnable[0]} is learnable: {why}")
    if len(terms) == 1 and terms[0][0] == 1:
        return terms[0][1]
    return Sum(tuple(terms))


__all__ = ["DECORATORS", "NODE_KINDS", "PROCESSORS", "read_tree"]
