"""The compiled tick for many state machines at once, as one numba loop over the rows.

``tick.py`` writes the tick as a walk of the tree that emits array operations: under ``jit``
they are traced once, but over a native batch's rows in numpy every node's handful of
operations is a numpy call each tick (~0.25 ms a tick for the push skill's 22 nodes, more
than its 21 rows' motion references). Here the same walk is done once, at trace time in
Python, into a flat program: per node, ``BEGIN``; per child, ``CHILD`` (its enabled flag from
the parent's registers), the child's own program, ``DONE`` (the child's status folded into the
parent's registers); then ``END`` (the node's status and new memory). A compiled loop runs the
program on each row, then the halting pass, exactly the operations of ``tick.py`` per node
(including on disabled subtrees, whose values the flags mask), so it returns what
``jax.vmap(tick)`` returns (tests/bt_compiled/test_property.py checks it against the reference
interpreter, and against ``jax.vmap(tick)`` on out-of-range statuses). ``row_tables`` builds a
tree's program once; ``tick_program`` runs it.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from mjxskill._numba import compiled
from mjxskill.bt_compiled.compile import CompiledTree
from mjxskill.ebt.nodes import Kind, Status

_LEAF, _BEGIN, _CHILD, _DONE, _END = range(5)
RUNNING, SUCCESS, FAILURE, NOT_TICKED = int(Status.RUNNING), int(Status.SUCCESS), int(Status.FAILURE), -1
_SEQUENCE, _SERIAL_STAR, _SELECTOR, _SELECTOR_STAR = (int(Kind.SEQUENCE), int(Kind.SERIAL_STAR), int(Kind.SELECTOR),
                                                      int(Kind.SELECTOR_STAR))
_PARALLEL, _PARALLEL_FS, _INVERTER, _FORCE_SUCCESS = (int(Kind.PARALLEL), int(Kind.PARALLEL_FS), int(Kind.INVERTER),
                                                      int(Kind.FORCE_SUCCESS))
_REPEAT, _RETRY, _TIMEOUT, _CONDITION = int(Kind.REPEAT), int(Kind.RETRY), int(Kind.TIMEOUT), int(Kind.CONDITION)


class RowTables(NamedTuple):
    """What the compiled loop reads of a tree: its program and its tables as int64 arrays."""

    program: np.ndarray
    kind: np.ndarray
    counts: np.ndarray  # Repeat, Retry and Timeout counts
    parent: np.ndarray
    leaf_index: np.ndarray
    leaf_ids: np.ndarray


@functools.lru_cache(maxsize=64)
def row_tables(ct: CompiledTree) -> RowTables:
    """``ct``'s program, (K, 4) int64 instructions (op, node, child, child position) in the
    order ``tick.py``'s walk emits its operations, and its tables (a tree of the same structure,
    the same program: ``CompiledTree`` hashes and compares by structure)."""
    ops: list[tuple[int, int, int, int]] = []

    def visit(nid: int) -> None:
        if ct.leaf_index[nid] >= 0:
            ops.append((_LEAF, nid, -1, 0))
            return
        ops.append((_BEGIN, nid, -1, 0))
        for i, cid in enumerate(ct.children(nid)):
            ops.append((_CHILD, nid, cid, i))
            visit(cid)
            ops.append((_DONE, nid, cid, i))
        ops.append((_END, nid, -1, 0))

    visit(0)
    return RowTables(np.array(ops, np.int64).reshape(-1, 4), *(np.asarray(a, np.int64) for a in (
        ct.kind, ct.count, ct.parent, ct.leaf_index, ct.leaf_ids)))


def tick_program(tables: RowTables, memory: npt.ArrayLike, live: npt.ArrayLike, leaf_status: npt.ArrayLike):
    """The tick of N machines of the tree of ``tables`` (``row_tables``): their ``memory`` (N, n)
    int32 and ``live`` (N, n) bool before it, each leaf's status (N, L) int. Returns the new
    memory, node statuses (N, n) int32, live (N, n) bool, the root statuses (N,) int32, the
    active leaves (N, L) bool and the leaves that start afresh (N, L) bool
    (``tick.started_leaves``)."""
    memory = np.ascontiguousarray(memory, np.int32)
    n_rows, n = memory.shape
    n_leaves = len(tables.leaf_ids)
    out = (np.empty((n_rows, n), np.int32), np.empty((n_rows, n), np.int32), np.empty((n_rows, n), bool),
           np.empty(n_rows, np.int32), np.empty((n_rows, n_leaves), bool), np.empty((n_rows, n_leaves), bool))
    _run(*tables, memory, np.ascontiguousarray(live, bool), np.ascontiguousarray(leaf_status, np.int64), *out)
    return out


@compiled
def _run(program, kind, count, parent, leaf_index, leaf_ids, memory, live_before, leaf_status,
         new_memory, node_status, live, root, active, started):
    n_rows, n = memory.shape
    enabled = np.zeros(n, np.bool_)
    status = np.zeros(n, np.int64)
    new_mem = np.zeros(n, np.int64)
    # a composite's registers while its children are visited: going on, its status so far
    # (``out``), its new memory so far (``acc``: a serial's resume index, a Parallel's done mask)
    going = np.zeros(n, np.bool_)
    out = np.zeros(n, np.int64)
    acc = np.zeros(n, np.int64)
    failed = np.zeros(n, np.bool_)
    running = np.zeros(n, np.bool_)
    for r in range(n_rows):
        enabled[0] = True  # every machine ticks its root
        for p in range(program.shape[0]):
            op, nid, cid, i = program[p, 0], program[p, 1], program[p, 2], program[p, 3]
            k, mem = kind[nid], np.int64(memory[r, nid])
            if op == _LEAF:
                s = leaf_status[r, leaf_index[nid]]
                # out of range: FAILURE (a Condition's value other than SUCCESS too)
                valid = s == SUCCESS if k == _CONDITION else (s == SUCCESS or s == RUNNING)
                status[nid] = s if valid else FAILURE
                new_mem[nid] = 0
            elif op == _BEGIN:
                going[nid] = enabled[nid]
                acc[nid] = mem if k == _PARALLEL else 0
                out[nid] = _go_on(k) if _serial(k) else RUNNING
                failed[nid] = False
                running[nid] = False
            elif op == _CHILD:
                enabled[cid] = _child_enabled(k, i, mem, enabled[nid], going[nid], acc[nid])
            elif op == _DONE:
                _fold_child(k, nid, i, status[cid], enabled[cid], mem, count[nid], going, out, acc, failed, running)
            else:  # _END
                if k == _PARALLEL:
                    status[nid] = FAILURE if failed[nid] else (RUNNING if running[nid] else SUCCESS)
                else:
                    status[nid] = out[nid]
                new_mem[nid] = acc[nid]
        _halt(r, parent, leaf_ids, enabled, status, new_mem, live_before, new_memory, node_status, live, root, active,
              started)


@compiled
def _serial(k):
    return k == _SEQUENCE or k == _SERIAL_STAR or k == _SELECTOR or k == _SELECTOR_STAR


@compiled
def _go_on(k):
    """The status a serial node goes on after: sequences on success, selectors on failure."""
    return SUCCESS if (k == _SEQUENCE or k == _SERIAL_STAR) else FAILURE


@compiled
def _child_enabled(k, i, mem, enabled, going, acc):
    """Whether child ``i`` of a node of kind ``k`` is ticked, given the node's registers."""
    if _serial(k):  # the starred kinds resume from the child that was running
        return going and (not (k == _SERIAL_STAR or k == _SELECTOR_STAR) or mem <= i)
    if k == _PARALLEL:  # the children that have not succeeded since it started
        return going and ((acc >> i) & 1) == 0
    if k == _PARALLEL_FS:
        return going
    return enabled  # a decorator ticks its child when it is ticked


@compiled
def _fold_child(k, nid, i, s, on, mem, count, going, out, acc, failed, running):
    """Child ``i``'s status ``s`` (ticked: ``on``) folded into node ``nid``'s registers."""
    if _serial(k):
        stop = on and s != _go_on(k)
        if stop:
            out[nid] = s
            if (k == _SERIAL_STAR or k == _SELECTOR_STAR) and s == RUNNING:
                acc[nid] = i
        going[nid] = going[nid] and not stop
    elif k == _PARALLEL:
        failed[nid] = failed[nid] or (on and s == FAILURE)
        running[nid] = running[nid] or (on and s == RUNNING)
        if on and s == SUCCESS:
            acc[nid] = acc[nid] | (np.int64(1) << i)
        going[nid] = going[nid] and not failed[nid]
    elif k == _PARALLEL_FS:
        stop = on and s != RUNNING
        if stop:
            out[nid] = s
        going[nid] = going[nid] and not stop
    elif k == _INVERTER:
        out[nid] = FAILURE if s == SUCCESS else (SUCCESS if s == FAILURE else s)
    elif k == _FORCE_SUCCESS:
        out[nid] = SUCCESS if s == FAILURE else s
    elif k == _REPEAT or k == _RETRY:
        restart = s == (SUCCESS if k == _REPEAT else FAILURE) and mem + 1 < count
        out[nid] = RUNNING if restart else s
        acc[nid] = mem + 1 if restart else mem
    else:  # Timeout: FAILURE once its child has run ``count`` consecutive ticks
        out[nid] = FAILURE if (s == RUNNING and mem + 1 >= count) else s
        acc[nid] = mem + 1


@compiled
def _halt(r, parent, leaf_ids, enabled, status, new_mem, live_before, new_memory, node_status, live, root, active,
          started):
    """Row r's halting pass (parents come before children in pre-order) and its outputs."""
    for nid in range(enabled.shape[0]):
        parent_live = True if parent[nid] < 0 else live[r, parent[nid]]
        on = parent_live and enabled[nid] and status[nid] == RUNNING
        live[r, nid] = on
        new_memory[r, nid] = new_mem[nid] if on else 0
        node_status[r, nid] = status[nid] if enabled[nid] else NOT_TICKED
    root[r] = status[0]
    for j in range(leaf_ids.shape[0]):
        active[r, j] = enabled[leaf_ids[j]]
        started[r, j] = enabled[leaf_ids[j]] and not live_before[r, leaf_ids[j]]
