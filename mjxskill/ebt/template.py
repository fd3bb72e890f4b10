"""A skill's behavior tree as a template over the primitive library, filled in for one use of the
skill in a plan.

A template is what a skill's ``tree`` in the YAML says (``mjxskill.scenario.skill_tree`` reads
and checks it): processors and decorators of ``mjxskill.ebt.nodes`` with their names, and
leaves naming a primitive of ``mjxskill.ebt.primitives`` with inputs. An input's value is a
number, a text (a choice), a list of values, a reference ``$name`` to a skill parameter or plan
argument (``$target.position.z``: an attribute of the object a plan argument names), or a sum
of numbers and references (``$push_height - $workpiece.position.z``). ``$label`` in a name is
the skill's label in the plan ("Name" or "Name#2").

``expand`` fills a template in: object arguments become the object's name (and its MJCF body,
``mjcf_body``, for the reader), a reference to a learnable parameter becomes a ``params``
entry (``"<label>.<parameter>"``: the optimizer's value is read at run time), every other value
is fixed into ``args`` (vectors and sums rounded to 1e-9, so printed trees show no float noise).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Union, cast

from mjxskill.ebt.nodes import Kind, Node
from mjxskill.ebt.primitives import INPUTS
from mjxskill.errors import PlanError

# What an object's attribute is: name -> its length (a vector's components are .x .y .z)
OBJECT_ATTRIBUTES = {"position": 3, "approach_offset": 3, "rpy_deg": 3, "size": None}
COMPONENTS = ("x", "y", "z")


@dataclass(frozen=True)
class Ref:
    """``$name`` (a skill parameter or plan argument) or ``$name.attribute[.component]``."""

    name: str
    path: tuple[str, ...] = ()

    def __str__(self) -> str:
        return "$" + ".".join((self.name, *self.path))


@dataclass(frozen=True)
class Sum:
    """Signed terms: ((+1 or -1, a number or a Ref), ...)."""

    terms: tuple[tuple[int, Union[float, Ref]], ...]


Value = Union[float, str, Ref, Sum, tuple]


@dataclass(frozen=True)
class LeafTemplate:
    """An action leaf: its name, primitive and inputs ((input, Value), ...) in file order."""

    name: str
    primitive: str
    inputs: tuple[tuple[str, Value], ...]


@dataclass(frozen=True)
class NodeTemplate:
    """A processor or decorator: kind, name, children (templates), count (Repeat/Retry/Timeout)."""

    kind: Kind
    name: str
    children: tuple
    count: int = 0


class Binding:
    """What filling a template in reads: the label, and per reference the skill parameter's
    fixed value, a learnable parameter's name, or the object a plan argument names.

    learnable(name) -> bool; fixed(name) -> float | tuple; obj(name) -> the scenario object
    (``WorldObject``) a plan argument names (raises for one that is no object with a pose)."""

    def __init__(self, label: str, learnable: Callable[[str], bool], fixed: Callable, obj: Callable):
        self.label, self.learnable, self.fixed, self.obj = label, learnable, fixed, obj

    def value(self, ref: Ref):
        """A number, a vector (tuple) or, without a path, the object a plan argument names."""
        if not ref.path:
            return self.fixed(ref.name)
        obj = self.obj(ref.name)
        value = getattr(obj.pose, ref.path[0]) if ref.path[0] in ("position", "rpy_deg") else getattr(obj, ref.path[0])
        if len(ref.path) > 1:
            index = COMPONENTS.index(ref.path[1])
            if index >= len(value):
                raise PlanError(f"{ref} of {obj.name}: its {ref.path[0]} has {len(value)} values")
            value = value[index]
        return tuple(float(v) for v in value) if hasattr(value, "__len__") else float(value)


def _number(value: float | Ref | Sum, binding: Binding) -> float:
    if isinstance(value, Ref):
        return float(binding.value(value))
    if isinstance(value, Sum):
        return round(sum(sign * _number(term, binding) for sign, term in value.terms), 9)
    return float(value)


def _vector(value: Ref | tuple, binding: Binding) -> tuple[float, ...]:
    items = binding.value(value) if isinstance(value, Ref) else tuple(_number(v, binding) for v in value)
    return tuple(round(float(v), 9) for v in items)


def _leaf(leaf: LeafTemplate, binding: Binding) -> Node:
    args, params = {}, {}
    signature = INPUTS[leaf.primitive]
    for name, value in leaf.inputs:
        kind = signature[name].kind
        # What an input of each kind holds (mjxskill.scenario.skill_tree checks it): an object, a
        # Ref; a number, a float, Ref or Sum; a vector, a Ref or a tuple
        if kind == "object":
            obj = binding.obj(cast(Ref, value).name)
            args[name] = obj.name
            args["mjcf_body"] = obj.mjcf_body
        elif isinstance(value, Ref) and not value.path and binding.learnable(value.name):
            params[name] = f"{binding.label}.{value.name}"
        elif kind == "number":
            args[name] = _number(cast(Union[float, Ref, Sum], value), binding)
        elif kind in ("vector3", "vector6"):
            args[name] = _vector(cast(Union[Ref, tuple], value), binding)
        else:
            args[name] = value
    return Node(Kind.ACTION, _name(leaf.name, binding), primitive=leaf.primitive, args=args, params=params)


def _name(text: str, binding: Binding) -> str:
    return text.replace("$label", binding.label)


def expand(template, binding: Binding) -> Node:
    """The eBT of ``template`` (a NodeTemplate or LeafTemplate) for one planned use."""
    if isinstance(template, LeafTemplate):
        return _leaf(template, binding)
    children = tuple(expand(child, binding) for child in template.children)
    return Node(template.kind, _name(template.name, binding), children, count=template.count)


def references(template) -> list[Ref]:
    """Every reference in ``template``, in file order."""
    if isinstance(template, NodeTemplate):
        return [r for child in template.children for r in references(child)]
    found: list[Ref] = []

    def visit(value):
        if isinstance(value, Ref):
            found.append(value)
        elif isinstance(value, Sum):
            for _, term in value.terms:
                visit(term)
        elif isinstance(value, tuple):
            for item in value:
                visit(item)

    for _, value in template.inputs:
        visit(value)
    return found


__all__ = ["COMPONENTS", "OBJECT_ATTRIBUTES", "Binding", "LeafTemplate", "NodeTemplate", "Ref", "Sum", "expand",
           "references"]
