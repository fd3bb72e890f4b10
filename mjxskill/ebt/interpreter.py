"""Reference eBT interpreter: plain Python, one tick at a time, written for clarity.

It is the specification the compiled tick (``mjxskill.bt_compiled``) is tested against, and the
BT the native-MuJoCo baseline runs. Semantics: see ``mjxskill/ebt/nodes.py``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, cast

from mjxskill.ebt.nodes import Kind, Node, Status

# leaf_fn(node_id, node) -> Status, called for every leaf ticked this tick.
LeafFn = Callable[[int, Node], Status]


@dataclass(frozen=True)
class TickResult:
    """What one tick of the whole tree did.

    status: the root's status.
    node_status: node id -> status for every node ticked this tick (pre-order ids).
    active_leaves: ids of the leaves ticked this tick, in tick order.
    """

    status: Status
    node_status: dict[int, Status]
    active_leaves: tuple[int, ...]


class Interpreter:
    """Ticks one tree; holds the per-node memory between ticks.

    Memory per node id: ``index`` (SerialStar/SelectorStar: first child still to tick),
    ``done`` (Parallel: ids of children that succeeded), ``count`` (Repeat/Retry: finished
    child runs; Timeout: consecutive ticks).
    """

    def __init__(self, tree: Node):
        self.tree = tree
        self.nodes: list[Node] = list(tree.walk())
        # child node ids of each node, by pre-order numbering
        self.children: list[list[int]] = [[] for _ in self.nodes]
        self._number(tree, 0)
        self.memory: dict[int, int | frozenset[int]] = {}
        # after a tick: the nodes ticked that, with all their ancestors, are still RUNNING
        self.live: set[int] = set()

    def _number(self, node: Node, node_id: int) -> int:
        next_id = node_id + 1
        for child in node.children:
            self.children[node_id].append(next_id)
            next_id = self._number(child, next_id)
        return next_id

    def _count(self, nid: int) -> int:
        """A SerialStar/SelectorStar's index or a Repeat/Retry/Timeout's count (0: none kept)."""
        return cast(int, self.memory.get(nid, 0))

    def _done(self, nid: int) -> frozenset[int]:
        """A Parallel's children that succeeded (none kept: none)."""
        return cast(frozenset[int], self.memory.get(nid, frozenset()))

    def reset(self) -> None:
        self.memory.clear()

    def tick(self, leaf_fn: LeafFn) -> TickResult:
        ticked: dict[int, Status] = {}
        order: list[int] = []
        status = self._tick(0, leaf_fn, ticked, order)
        # Halting: a node keeps its memory only if it was ticked and it and all its ancestors
        # are still RUNNING. A node not ticked was preempted; a node under a finished one
        # (ParallelFs returning, Timeout firing, Repeat restarting its child) starts afresh.
        live = self._still_running(ticked)
        self.live = live  # the nodes that carry on at the next tick (a caller may read them)
        for node_id in list(self.memory):
            if node_id not in live:
                del self.memory[node_id]
        return TickResult(status, ticked, tuple(order))

    def _still_running(self, ticked: dict[int, Status]) -> set[int]:
        live: set[int] = set()
        stack = [0]
        while stack:
            nid = stack.pop()
            if ticked.get(nid) == Status.RUNNING:
                live.add(nid)
                stack.extend(self.children[nid])
        return live

    def _tick(self, nid: int, leaf_fn: LeafFn, ticked: dict[int, Status], order: list[int]) -> Status:
        node = self.nodes[nid]
        kids = self.children[nid]
        kind = node.kind
        mem = self.memory

        def child(cid: int) -> Status:
            return self._tick(cid, leaf_fn, ticked, order)

        if kind in (Kind.ACTION, Kind.CONDITION):
            status = Status(leaf_fn(nid, node))
            if kind == Kind.CONDITION and status == Status.RUNNING:
                raise ValueError(f"condition {node.name!r} (node {nid}) returned RUNNING")
            order.append(nid)
        elif kind in (Kind.SEQUENCE, Kind.SERIAL_STAR, Kind.SELECTOR, Kind.SELECTOR_STAR):
            # Sequences stop on the first non-SUCCESS child, selectors on the first non-FAILURE.
            go_on = Status.SUCCESS if kind in (Kind.SEQUENCE, Kind.SERIAL_STAR) else Status.FAILURE
            has_memory = kind in (Kind.SERIAL_STAR, Kind.SELECTOR_STAR)
            start = self._count(nid) if has_memory else 0
            status = go_on
            for i in range(start, len(kids)):
                status = child(kids[i])
                if status != go_on:
                    if status == Status.RUNNING and has_memory:
                        mem[nid] = i
                    break
        elif kind == Kind.PARALLEL:
            done = set(self._done(nid))
            status = Status.SUCCESS
            for cid in kids:
                if cid in done:
                    continue
                s = child(cid)
                if s == Status.FAILURE:
                    status = Status.FAILURE
                    break
                if s == Status.SUCCESS:
                    done.add(cid)
                else:
                    status = Status.RUNNING
            if status == Status.RUNNING:
                mem[nid] = frozenset(done)
        elif kind == Kind.PARALLEL_FS:
            status = Status.RUNNING
            for cid in kids:
                s = child(cid)
                if s != Status.RUNNING:
                    status = s
                    break
        elif kind == Kind.INVERTER:
            s = child(kids[0])
            status = {Status.SUCCESS: Status.FAILURE, Status.FAILURE: Status.SUCCESS}.get(s, s)
        elif kind == Kind.FORCE_SUCCESS:
            s = child(kids[0])
            status = Status.SUCCESS if s == Status.FAILURE else s
        elif kind in (Kind.REPEAT, Kind.RETRY):
            # Repeat counts successes and gives up on failure; Retry counts failures and
            # stops on success.
            counted = Status.SUCCESS if kind == Kind.REPEAT else Status.FAILURE
            s = child(kids[0])
            status = s
            if s == counted:
                n = self._count(nid) + 1
                if n < node.count:
                    mem[nid] = n  # the child finished, so it restarts fresh next tick
                    status = Status.RUNNING
        elif kind == Kind.TIMEOUT:
            n = self._count(nid) + 1
            s = child(kids[0])
            status = s
            if s == Status.RUNNING:
                if n >= node.count:
                    status = Status.FAILURE  # the child is halted with the finished node
                else:
                    mem[nid] = n
        else:  # pragma: no cover - Kind is closed
            raise AssertionError(kind)

        ticked[nid] = status
        return status


def run_script(tree: Node, script: list[dict[int, Status]] | list[list[Status]]) -> list[TickResult]:
    """Ticks ``tree`` once per entry of ``script``.

    Each entry gives the status of every leaf for that tick, either as a dict node id -> status
    or as a list in leaf order (``tree.leaves()``). Leaves not ticked ignore their entry.
    """
    interp = Interpreter(tree)
    leaf_ids = [i for i, n in enumerate(interp.nodes) if n.is_leaf]
    results = []
    for entry in script:
        table: dict[int, Status] = entry if isinstance(entry, dict) else dict(zip(leaf_ids, entry))
        results.append(interp.tick(lambda nid, node: table[nid]))  # called within this iteration's tick
    return results
