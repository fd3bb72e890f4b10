"""Extended behavior tree (eBT) nodes: an immutable tree of processors, decorators and leaves.

Semantics (pinned by ``tests/ebt/test_interpreter.py``; the compiled tick in
``mjxskill.bt_compiled`` must match the reference interpreter in ``interpreter.py``):

* A tick returns RUNNING, SUCCESS or FAILURE. Children are ticked left to right.
* **Halting.** After every tick a node keeps its memory only if it was ticked in that tick and
  it and all its ancestors returned RUNNING. A node not ticked was preempted (halted); a node
  inside one that finished (ParallelFs returning, Timeout firing, Repeat restarting its child)
  starts afresh on its next tick.
* ``Sequence`` (``->``): no memory; ticks children from the first on every tick; returns the
  first non-SUCCESS status; SUCCESS if all succeed (SkiROS "Serial"; py_trees memory=False).
* ``SerialStar`` (``->*``): a sequence with memory; children that succeeded are not ticked
  again until the node finishes (py_trees memory=True, BehaviorTree.CPP ``Sequence``).
* ``Selector`` (``?``) / ``SelectorStar`` (``?*``): fallback without / with memory; returns
  the first non-FAILURE status; FAILURE if all fail.
* ``Parallel`` (``||FF``, first-fail): ticks every child that has not succeeded since the node
  started; FAILURE as soon as one fails (the others are halted), SUCCESS once all succeeded.
* ``ParallelFs`` (``||FS``, first-success): ticks children left to right and returns the status
  of the first child that finishes (SUCCESS or FAILURE); the children after it are not ticked
  and all others are halted (preempted). RUNNING while every child runs.
* Decorators, one child each: ``Inverter`` (``!``) swaps SUCCESS and FAILURE; ``ForceSuccess``
  (``+``) turns FAILURE into SUCCESS; ``Repeat(n)`` (``*n``) returns RUNNING after each of the
  child's first n-1 successes and SUCCESS after the n-th, FAILURE when the child fails;
  ``Retry(n)`` (``rn``) returns RUNNING after each of the child's first n-1 failures, FAILURE
  after the n-th and SUCCESS when the child succeeds; ``Timeout(n)`` (``tn``) returns the child's
  status, but FAILURE (halting the child) when the child is still RUNNING on the node's n-th
  consecutive tick. RUNNING passes through all of them.
* Leaves: ``Action`` (may return RUNNING) and ``Condition`` (must not return RUNNING). A leaf's
  ``primitive`` names the leaf program that implements it; ``args`` are its fixed arguments and
  ``params`` maps the program's inputs to skill parameter names (learnable or set by the plan).

Nodes are identified by their pre-order index (parent before children, left to right), which is
the order ``walk`` yields and the order the compiled tree uses.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Iterator, Mapping

from mjxskill.errors import quote


class Status(enum.IntEnum):
    """Tick result. The integer values are the ones the compiled tree uses."""

    RUNNING = 0
    SUCCESS = 1
    FAILURE = 2


class Kind(enum.IntEnum):
    """Node kinds. The integer values are the ones the compiled tree uses."""

    SEQUENCE = 0
    SERIAL_STAR = 1
    SELECTOR = 2
    SELECTOR_STAR = 3
    PARALLEL = 4  # first-fail
    PARALLEL_FS = 5  # first-success, preempting
    INVERTER = 6
    FORCE_SUCCESS = 7
    REPEAT = 8
    RETRY = 9
    TIMEOUT = 10
    ACTION = 11
    CONDITION = 12


COMPOSITES = frozenset(
    {Kind.SEQUENCE, Kind.SERIAL_STAR, Kind.SELECTOR, Kind.SELECTOR_STAR, Kind.PARALLEL, Kind.PARALLEL_FS}
)
DECORATORS = frozenset({Kind.INVERTER, Kind.FORCE_SUCCESS, Kind.REPEAT, Kind.RETRY, Kind.TIMEOUT})
LEAVES = frozenset({Kind.ACTION, Kind.CONDITION})

SYMBOLS = {
    Kind.SEQUENCE: "->",
    Kind.SERIAL_STAR: "->*",
    Kind.SELECTOR: "?",
    Kind.SELECTOR_STAR: "?*",
    Kind.PARALLEL: "||FF",
    Kind.PARALLEL_FS: "||FS",
    Kind.INVERTER: "!",
    Kind.FORCE_SUCCESS: "+",
    Kind.REPEAT: "*",
    Kind.RETRY: "r",
    Kind.TIMEOUT: "t",
    Kind.ACTION: "A",
    Kind.CONDITION: "C",
}


@dataclass(frozen=True)
class Node:
    """One eBT node. Build trees with the helper constructors below.

    kind: what the node does (see the module docstring).
    name: a label for printing (skill or primitive name).
    children: sub-trees; composites have >= 1, decorators exactly 1, leaves 0.
    count: n of Repeat/Retry/Timeout (ticks for Timeout), 0 otherwise.
    primitive: leaf program name (leaves only).
    args: fixed leaf arguments, e.g. {"stiffness": (500, 500, 0, 50, 50, 50)}.
    params: leaf input -> skill parameter name, e.g. {"offset_x": "Slide.offset_x_start"}.
    """

    kind: Kind
    name: str = ""
    children: tuple["Node", ...] = ()
    count: int = 0
    primitive: str = ""
    args: Mapping[str, object] = field(default_factory=dict)
    params: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self):
        if self.kind in COMPOSITES and not self.children:
            raise ValueError(f"{self.kind.name} node {quote(self.name)} needs at least one child")
        if self.kind in DECORATORS and len(self.children) != 1:
            raise ValueError(f"{self.kind.name} node {quote(self.name)} needs exactly one child")
        if self.kind in LEAVES and self.children:
            raise ValueError(f"leaf {quote(self.name)} cannot have children")
        if self.kind in (Kind.REPEAT, Kind.RETRY, Kind.TIMEOUT) and self.count < 1:
            raise ValueError(f"{self.kind.name} node {quote(self.name)} needs count >= 1, got {self.count}")

    @property
    def is_leaf(self) -> bool:
        return self.kind in LEAVES

    def walk(self) -> Iterator["Node"]:
        """Pre-order traversal: the node ids used by interpreters and the compiler."""
        yield self
        for child in self.children:
            yield from child.walk()

    def leaves(self) -> list["Node"]:
        return [n for n in self.walk() if n.is_leaf]

    def depth(self) -> int:
        return 1 + max((c.depth() for c in self.children), default=0)

    def __hash__(self):  # args/params are dicts: hash by identity-free structure
        return hash((self.kind, self.name, self.children, self.count, self.primitive))


def _composite(kind: Kind):
    def make(name: str, *children: Node) -> Node:
        return Node(kind, name, tuple(children))

    return make


sequence = _composite(Kind.SEQUENCE)
serial_star = _composite(Kind.SERIAL_STAR)
selector = _composite(Kind.SELECTOR)
selector_star = _composite(Kind.SELECTOR_STAR)
parallel = _composite(Kind.PARALLEL)
parallel_fs = _composite(Kind.PARALLEL_FS)


def inverter(child: Node, name: str = "not") -> Node:
    return Node(Kind.INVERTER, name, (child,))


def force_success(child: Node, name: str = "force_success") -> Node:
    return Node(Kind.FORCE_SUCCESS, name, (child,))


def repeat(child: Node, n: int, name: str = "repeat") -> Node:
    return Node(Kind.REPEAT, name, (child,), count=n)


def retry(child: Node, n: int, name: str = "retry") -> Node:
    return Node(Kind.RETRY, name, (child,), count=n)


def timeout(child: Node, ticks: int, name: str = "timeout") -> Node:
    return Node(Kind.TIMEOUT, name, (child,), count=ticks)


def action(name: str, primitive: str = "", args=None, params=None) -> Node:
    return Node(Kind.ACTION, name, primitive=primitive or name, args=dict(args or {}), params=dict(params or {}))


def condition(name: str, primitive: str = "", args=None, params=None) -> Node:
    return Node(Kind.CONDITION, name, primitive=primitive or name, args=dict(args or {}), params=dict(params or {}))


def render(tree: Node, indent: str = "  ") -> str:
    """The tree as indented text with processor symbols, one node a line."""
    lines: list[str] = []

    def visit(node: Node, depth: int):
        label = SYMBOLS[node.kind]
        if node.kind in (Kind.REPEAT, Kind.RETRY, Kind.TIMEOUT):
            label += str(node.count)
        text = f"{indent * depth}{label} {node.name}".rstrip()
        if node.is_leaf:
            extras = [f"{k}={v}" for k, v in node.args.items()] + [f"{k}<-{v}" for k, v in node.params.items()]
            if node.primitive != node.name:
                extras.insert(0, node.primitive)
            if extras:
                text += " [" + ", ".join(extras) + "]"
        lines.append(text)
        for child in node.children:
            visit(child, depth + 1)

    visit(tree, 0)
    return "\n".join(lines)
