"""eBT -> flat, static description of the tree that the jittable tick runs over.

The tree is numbered in pre-order (``Node.walk``): parent before children, left to right, the
same ids the reference interpreter (``mjxskill.ebt.interpreter``) reports. Everything here is
host-side numpy / Python data computed once per tree; ``tick`` reads it at trace time, so it
ends up as constants in the compiled program (the way Brax and MuJoCo Playground bake site ids
into the trace).

A ``CompiledTree`` is hashable and compares by the tree's *structure* (kinds, shape, counts), so
it can be a static argument of ``jax.jit``: two trees that differ only in their leaves'
primitives, args or params share one compiled tick.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, NamedTuple

import numpy as np

from mjxskill.ebt.nodes import Kind, Node
from mjxskill.errors import quote

# Parallel (first-fail) keeps "which children already succeeded" as bits of one int32 memory
# slot, so it can have at most 31 children.
MAX_PARALLEL_CHILDREN = 31


class LeafSpec(NamedTuple):
    """One leaf program to run: what the rollout needs to build the leaf's behaviour.

    node_id: the leaf's pre-order node id.
    kind: Kind.ACTION or Kind.CONDITION.
    name: the leaf's label.
    primitive: name of the leaf program implementing it.
    primitive_index: index of ``primitive`` in ``CompiledTree.primitives``.
    args: fixed arguments of the program.
    params: program input -> skill parameter name.
    """

    node_id: int
    kind: Kind
    name: str
    primitive: str
    primitive_index: int
    args: Mapping[str, object]
    params: Mapping[str, str]


@dataclass(frozen=True, eq=False)
class CompiledTree:
    """A behavior tree as flat arrays in pre-order node ids (n nodes, L leaves).

    kind: (n,) int32, ``Kind`` values.
    parent: (n,) int32, parent id, -1 for the root.
    child_table: (n, max_children) int32, child ids left to right, padded with -1.
    child_count: (n,) int32, number of children.
    count: (n,) int32, n of Repeat/Retry/Timeout, 0 otherwise.
    leaf_ids: (L,) int32, node ids of the leaves in pre-order (= tick order).
    leaf_index: (n,) int32, position of a leaf in ``leaf_ids``, -1 for inner nodes.
    names: (n,) node labels.
    leaves: (L,) ``LeafSpec`` per leaf, in ``leaf_ids`` order.
    primitives: distinct leaf program names in order of first appearance; a rollout can
        dispatch with ``lax.switch(leaf.primitive_index, programs)``.
    tree: the source tree.
    """

    kind: np.ndarray
    parent: np.ndarray
    child_table: np.ndarray
    child_count: np.ndarray
    count: np.ndarray
    leaf_ids: np.ndarray
    leaf_index: np.ndarray
    names: tuple[str, ...]
    leaves: tuple[LeafSpec, ...]
    primitives: tuple[str, ...]
    tree: Node

    @property
    def num_nodes(self) -> int:
        return int(self.kind.shape[0])

    @property
    def num_leaves(self) -> int:
        return int(self.leaf_ids.shape[0])

    def children(self, node_id: int) -> tuple[int, ...]:
        """Child ids of ``node_id``, left to right."""
        return tuple(int(c) for c in self.child_table[node_id, : self.child_count[node_id]])

    def _structure(self) -> tuple:
        return (
            tuple(self.kind.tolist()),
            tuple(self.parent.tolist()),
            tuple(self.count.tolist()),
        )

    # The tick depends on the structure only (kinds, parents in pre-order, counts), which fixes
    # the tree's shape; leaf programs and names do not change the compiled tick.
    def __hash__(self) -> int:
        return hash(self._structure())

    def __eq__(self, other) -> bool:
        return isinstance(other, CompiledTree) and self._structure() == other._structure()


def compile_tree(tree: Node) -> CompiledTree:
    """Flattens ``tree`` (an eBT root ``Node``) into a ``CompiledTree``.

    Raises ValueError for a Parallel node with more than 31 children (its memory is a bitmask)
    or for a node whose kind is not a ``Kind``.
    """
    if not isinstance(tree, Node):
        raise TypeError(f"compile_tree expects an mjxskill.ebt.nodes.Node, got {type(tree).__name__}")
    nodes: list[Node] = list(tree.walk())
    n = len(nodes)
    parent = np.full(n, -1, np.int32)
    children: list[list[int]] = [[] for _ in range(n)]

    def number(node: Node, node_id: int) -> int:
        next_id = node_id + 1
        for child in node.children:
            parent[next_id] = node_id
            children[node_id].append(next_id)
            next_id = number(child, next_id)
        return next_id

    number(tree, 0)

    for node_id, node in enumerate(nodes):
        if not isinstance(node.kind, Kind):
            raise ValueError(f"node {node_id} ({quote(node.name)}) has kind {quote(node.kind)}, not an mjxskill Kind")
        if node.kind == Kind.PARALLEL and len(node.children) > MAX_PARALLEL_CHILDREN:
            raise ValueError(
                f"PARALLEL node {node_id} ({quote(node.name)}) has {len(node.children)} children; the compiled "
                f"tick supports at most {MAX_PARALLEL_CHILDREN} (nest Parallel nodes to get more)"
            )

    max_children = max(1, max(len(c) for c in children))
    child_table = np.full((n, max_children), -1, np.int32)
    for node_id, kids in enumerate(children):
        child_table[node_id, : len(kids)] = kids

    leaf_ids = np.array([i for i, node in enumerate(nodes) if node.is_leaf], np.int32)
    leaf_index = np.full(n, -1, np.int32)
    leaf_index[leaf_ids] = np.arange(len(leaf_ids), dtype=np.int32)

    primitives: list[str] = []
    leaves: list[LeafSpec] = []
    for node_id in leaf_ids.tolist():
        node = nodes[node_id]
        if node.primitive not in primitives:
            primitives.append(node.primitive)
        leaves.append(
            LeafSpec(
                node_id=node_id,
                kind=node.kind,
                name=node.name,
                primitive=node.primitive,
                primitive_index=primitives.index(node.primitive),
                args=dict(node.args),
                params=dict(node.params),
            )
        )

    for array in (parent, child_table, leaf_ids, leaf_index):
        array.setflags(write=False)
    kind = np.array([int(node.kind) for node in nodes], np.int32)
    child_count = np.array([len(c) for c in children], np.int32)
    count = np.array([node.count for node in nodes], np.int32)
    for array in (kind, child_count, count):
        array.setflags(write=False)

    return CompiledTree(
        kind=kind,
        parent=parent,
        child_table=child_table,
        child_count=child_count,
        count=count,
        leaf_ids=leaf_ids,
        leaf_index=leaf_index,
        names=tuple(node.name for node in nodes),
        leaves=tuple(leaves),
        primitives=tuple(primitives),
        tree=tree,
    )
