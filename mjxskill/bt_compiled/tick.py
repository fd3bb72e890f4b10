"""The compiled tick: one pure, jittable, vmappable step of a behavior tree's state machine.

``tick(ct, state, leaf_status)`` does what ``mjxskill.ebt.interpreter.Interpreter.tick`` does
(semantics in ``mjxskill/ebt/nodes.py``), given the status every leaf *would* return this tick;
it reports which leaves were actually ticked (``active``), so a rollout runs every leaf program
each control step and keeps the results of the active ones.

How it compiles: the tree is static, so ``tick`` walks it in Python at trace time and emits a
handful of scalar ``jnp.where`` ops per node (no ``lax.cond``, no loop over nodes at run time).
Each node gets an ``enabled`` flag (is it ticked this tick?) from its parent; a node's status
is only ever used behind its ``enabled`` flag, so disabled subtrees compute harmless garbage.
The result is straight-line, branch-free code (about 20 scalar ops per node) that vmaps over
batches of independent state machines; op count, compile time and run time grow linearly with
the number of nodes (benchmarks/bt_tick.py: the push skill's 8-node tree compiles in well under a
second, and a tick costs well under a microsecond per machine on CPU inside a scan). A variant
that writes each composite as vector ops over its children (cumsum for "first child that
stops") was measured too: no faster at batch 1024 and 2-5x slower at batch 1 on CPU.

``started_leaves(ct, previous_state, active)`` tells which active leaves start afresh (their
programs must reset) rather than carry on from the last tick.

``tick_rows(ct, state, leaf_status)`` is the same tick over N machines at once on numpy arrays
(state fields (N, n), statuses (N, L)), what a native batch's rows run: this walk flattened once
into a program of per-node instructions that a compiled loop runs on each row
(``mjxskill.bt_compiled.rows``).

Out-of-range leaf statuses: an Action's value other than RUNNING (0) or SUCCESS (1) counts as
FAILURE. A Condition returning RUNNING is an error in the interpreter, but a jitted function
cannot raise, so a Condition's value other than SUCCESS counts as FAILURE.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjxskill.bt_compiled.compile import CompiledTree
from mjxskill.bt_compiled.rows import row_tables, tick_program
from mjxskill.ebt.nodes import Kind, Status

RUNNING = int(Status.RUNNING)
SUCCESS = int(Status.SUCCESS)
FAILURE = int(Status.FAILURE)
NOT_TICKED = -1

_KINDS_WITH_MEMORY = frozenset(
    {Kind.SERIAL_STAR, Kind.SELECTOR_STAR, Kind.PARALLEL, Kind.REPEAT, Kind.RETRY, Kind.TIMEOUT}
)


class BTState(NamedTuple):
    """State of one behavior-tree state machine (n nodes); batch it with ``jax.vmap``.

    memory: (n,) int32, per node, 0 = fresh (never ticked, halted or finished):
        SerialStar / SelectorStar: index of the child to resume from;
        Parallel (first-fail): bitmask of children that succeeded since the node started
        (bit i = i-th child);
        Repeat / Retry: number of child runs counted so far (successes / failures);
        Timeout: number of consecutive ticks so far;
        other kinds: always 0.
    node_status: (n,) int32, each node's status in the last tick, -1 where not ticked
        (all -1 before the first tick); for tracing and plots, not read by ``tick``.
    live: (n,) bool, the node was ticked in the last tick and it and all its ancestors
        returned RUNNING: it carries on at its next tick (everything else starts afresh).
    """

    memory: jax.Array | np.ndarray  # numpy rows in ``tick_rows``
    node_status: jax.Array | np.ndarray
    live: jax.Array | np.ndarray


def init_state(ct: CompiledTree) -> BTState:
    """A fresh state machine: all memory 0, nothing ticked yet."""
    return _fresh((ct.num_nodes,), jnp)


def _fresh(shape: tuple, xp) -> BTState:
    """Fresh state machines of ``shape`` (leading machines, then nodes) in namespace ``xp``."""
    return BTState(memory=xp.zeros(shape, xp.int32), node_status=xp.full(shape, NOT_TICKED, xp.int32),
                   live=xp.zeros(shape, bool))


def tick(ct: CompiledTree, state: BTState, leaf_status: jax.Array) -> tuple[BTState, jax.Array, jax.Array]:
    """Ticks the tree once.

    Args:
        ct: the compiled tree (static: pass it with ``static_argnums`` or close over it).
        state: ``BTState`` with (n,) fields.
        leaf_status: (L,) int, the status each leaf returns if it is ticked this tick, in
            ``ct.leaf_ids`` order (RUNNING=0, SUCCESS=1, FAILURE=2).

    Returns:
        new_state: ``BTState``; ``new_state.node_status`` (n,) holds every node's status this
            tick, -1 where not ticked.
        root_status: () int32.
        active: (L,) bool, the leaves ticked this tick.
    """
    leaf_status = jnp.asarray(leaf_status)
    _check_inputs(ct, state, leaf_status, ())
    return _tick(ct, state, leaf_status, jnp)


def tick_rows(ct: CompiledTree, state: BTState, leaf_status: np.ndarray) -> tuple[BTState, np.ndarray, np.ndarray]:
    """``tick`` for N machines at once in numpy: ``state`` with (N, n) fields, ``leaf_status``
    (N, L). Returns the new state ((N, n) fields), the root statuses (N,) and the active leaves
    (N, L), what ``jax.vmap(tick)`` returns for the same rows."""
    leaf_status = np.asarray(leaf_status)
    if leaf_status.ndim != 2:
        raise ValueError(f"leaf_status has shape {leaf_status.shape}; tick_rows needs (N, {ct.num_leaves}): a row per machine")
    _check_inputs(ct, state, leaf_status, leaf_status.shape[:1])
    if state.live.dtype != bool:  # ``~live`` (started_leaves) would be a bitwise not
        raise ValueError(f"state.live must be bool, got dtype {state.live.dtype}")
    memory, node_status, live, root, active, _ = tick_program(row_tables(ct), state.memory, state.live, leaf_status)
    return BTState(memory, node_status, live), root, active


def init_rows(ct: CompiledTree, n: int) -> BTState:
    """``n`` fresh state machines for ``tick_rows``: numpy fields (n, nodes), as ``init_state``'s."""
    return _fresh((n, ct.num_nodes), np)


def _tick(ct: CompiledTree, state: BTState, leaf_status, xp) -> tuple[BTState, Any, Any]:
    """The tick in namespace ``xp`` (jax.numpy): every per-node value is indexed ``[..., k]`` and
    stacked on the last axis, so leading axes would be machines."""
    walk = _Walk(ct, _sanitized(ct, leaf_status, xp), state.memory.astype(xp.int32), xp)
    root_status = walk.visit(0, xp.ones(leaf_status.shape[:-1], dtype=bool))  # every machine ticks its root
    live = _live(ct, walk.enabled, walk.status, xp)
    new_state = BTState(
        memory=xp.where(live, _stacked(walk.new_memory, xp), 0),
        node_status=xp.where(_stacked(walk.enabled, xp), _stacked(walk.status, xp), NOT_TICKED),
        live=live,
    )
    active = _stacked([walk.enabled[int(nid)] for nid in ct.leaf_ids], xp)
    return new_state, root_status, active


def _stacked(values: list, xp):
    """Per-node values (scalars and per-machine arrays mixed) stacked on a last axis."""
    return xp.stack(xp.broadcast_arrays(*values), axis=-1)


def _check_inputs(ct: CompiledTree, state: BTState, leaf_status, rows: tuple) -> None:
    """Raises ValueError unless ``leaf_status`` is ``rows`` + (L,) integer and every state field
    is ``rows`` + (n,)."""
    if leaf_status.shape != rows + (ct.num_leaves,):
        raise ValueError(
            f"leaf_status has shape {leaf_status.shape}; this tree has {ct.num_leaves} leaves, so it "
            f"must be {rows + (ct.num_leaves,)}" + ("" if rows else " (use jax.vmap for batches)")
        )
    if not np.issubdtype(leaf_status.dtype, np.integer):
        raise ValueError(f"leaf_status must hold integer Status values, got dtype {leaf_status.dtype}")
    for field, value in zip(state._fields, state):
        if value.shape != rows + (ct.num_nodes,):
            raise ValueError(f"state.{field} has shape {value.shape}; this tree needs {rows + (ct.num_nodes,)}")


def _sanitized(ct: CompiledTree, leaf_status, xp):
    """int32 ``leaf_status`` (..., L) with out-of-range values mapped to FAILURE in one
    vectorised pass (see the module docstring)."""
    leaf_status = leaf_status.astype(xp.int32)
    is_condition = ct.kind[ct.leaf_ids] == int(Kind.CONDITION)
    valid = xp.where(is_condition, leaf_status == SUCCESS, (leaf_status == SUCCESS) | (leaf_status == RUNNING))
    return xp.where(valid, leaf_status, FAILURE)


class _Walk:
    """One tick's trace-time walk of the tree, in pre-order from the root.

    ``visit(nid, on)`` emits node ``nid``'s ops given its ``enabled`` flag ``on`` (is it ticked
    this tick?), recursing into its children through the visitor of its kind (``_VISITORS``),
    and records per node: ``enabled`` (traced bool), ``status`` (traced int32, valid where
    enabled) and ``new_memory`` (traced int32, before halting). A visitor returns the node's
    status and new memory (0 for kinds without memory); ``mem`` is the node's memory, None for
    kinds without it.
    """

    def __init__(self, ct: CompiledTree, leaf_status, memory, xp):
        self.ct, self.leaf_status, self.memory, self.xp = ct, leaf_status, memory, xp
        n = ct.num_nodes
        self.enabled: list = [None] * n
        self.status: list = [None] * n
        self.new_memory: list = [None] * n

    def visit(self, nid: int, on) -> jax.Array:
        kind = Kind(int(self.ct.kind[nid]))
        mem = self.memory[..., nid] if kind in _KINDS_WITH_MEMORY else None
        out, new_mem = _VISITORS[kind](self, nid, kind, on, mem)
        self.enabled[nid] = on
        self.status[nid] = self.xp.asarray(out, dtype=self.xp.int32)
        self.new_memory[nid] = self.xp.asarray(new_mem, dtype=self.xp.int32)
        return self.status[nid]

    def leaf(self, nid, kind, on, mem):
        return self.leaf_status[..., int(self.ct.leaf_index[nid])], 0

    def serial(self, nid, kind, on, mem):
        """Sequences go on while children succeed, selectors while they fail; the starred kinds
        resume from the child that was running (children before it count as done)."""
        go_on = SUCCESS if kind in (Kind.SEQUENCE, Kind.SERIAL_STAR) else FAILURE
        has_memory = kind in (Kind.SERIAL_STAR, Kind.SELECTOR_STAR)
        going = on
        out = go_on
        new_mem = 0
        for i, cid in enumerate(self.ct.children(nid)):
            child_on = going & (mem <= i) if has_memory else going
            s = self.visit(cid, child_on)
            stop = child_on & (s != go_on)
            out = self.xp.where(stop, s, out)
            if has_memory:
                new_mem = self.xp.where(stop & (s == RUNNING), i, new_mem)
            going = going & ~stop
        return out, new_mem

    def parallel(self, nid, kind, on, mem):
        """First-fail Parallel: ticks the children that have not succeeded since it started."""
        done = mem
        going = on
        failed = False
        running = False
        for i, cid in enumerate(self.ct.children(nid)):
            child_on = going & (((done >> i) & 1) == 0)
            s = self.visit(cid, child_on)
            failed = failed | (child_on & (s == FAILURE))
            running = running | (child_on & (s == RUNNING))
            done = self.xp.where(child_on & (s == SUCCESS), done | (1 << i), done)
            going = going & ~failed  # the children after a failure are not ticked
        return self.xp.where(failed, FAILURE, self.xp.where(running, RUNNING, SUCCESS)), done

    def parallel_fs(self, nid, kind, on, mem):
        """First-stop Parallel: the first child that does not return RUNNING decides."""
        going = on
        out = RUNNING
        for cid in self.ct.children(nid):
            s = self.visit(cid, going)
            stop = going & (s != RUNNING)
            out = self.xp.where(stop, s, out)
            going = going & ~stop
        return out, 0

    def inverter(self, nid, kind, on, mem):
        s = self.visit(self.ct.children(nid)[0], on)
        return self.xp.where(s == SUCCESS, FAILURE, self.xp.where(s == FAILURE, SUCCESS, s)), 0

    def force_success(self, nid, kind, on, mem):
        s = self.visit(self.ct.children(nid)[0], on)
        return self.xp.where(s == FAILURE, SUCCESS, s), 0

    def counted(self, nid, kind, on, mem):
        """Repeat counts successes, Retry failures; below n, the node restarts its (finished)
        child on the next tick and reports RUNNING."""
        counted = SUCCESS if kind == Kind.REPEAT else FAILURE
        s = self.visit(self.ct.children(nid)[0], on)
        runs = mem + 1
        restart = (s == counted) & (runs < int(self.ct.count[nid]))
        return self.xp.where(restart, RUNNING, s), self.xp.where(restart, runs, mem)

    def timeout(self, nid, kind, on, mem):
        """FAILURE once its child has been RUNNING for ``count`` consecutive ticks."""
        ticks = mem + 1
        s = self.visit(self.ct.children(nid)[0], on)
        fire = (s == RUNNING) & (ticks >= int(self.ct.count[nid]))
        return self.xp.where(fire, FAILURE, s), ticks


_VISITORS = {
    Kind.ACTION: _Walk.leaf,
    Kind.CONDITION: _Walk.leaf,
    Kind.SEQUENCE: _Walk.serial,
    Kind.SERIAL_STAR: _Walk.serial,
    Kind.SELECTOR: _Walk.serial,
    Kind.SELECTOR_STAR: _Walk.serial,
    Kind.PARALLEL: _Walk.parallel,
    Kind.PARALLEL_FS: _Walk.parallel_fs,
    Kind.INVERTER: _Walk.inverter,
    Kind.FORCE_SUCCESS: _Walk.force_success,
    Kind.REPEAT: _Walk.counted,
    Kind.RETRY: _Walk.counted,
    Kind.TIMEOUT: _Walk.timeout,
}


def _live(ct: CompiledTree, enabled: list, status: list, xp):
    """(n,) bool, the halting pass: a node keeps its memory only if it was ticked and it and all
    its ancestors returned RUNNING. Parents come before children in pre-order, so one pass
    suffices."""
    live_flags: list = [None] * ct.num_nodes
    for nid in range(ct.num_nodes):
        parent_live = xp.asarray(True) if ct.parent[nid] < 0 else live_flags[int(ct.parent[nid])]
        live_flags[nid] = parent_live & enabled[nid] & (status[nid] == RUNNING)
    return _stacked(live_flags, xp)


def started_leaves(ct: CompiledTree, previous: BTState, active: jax.Array | np.ndarray) -> jax.Array | np.ndarray:
    """(L,) bool: leaves ticked this tick that were not running on from the last one.

    A leaf program with internal state (a motion generator's trajectory start, a spiral's
    phase) must restart for these: the leaf is new, was halted, finished, or sits under a node
    that finished (e.g. a Repeat restarting its child ticks the same leaf in consecutive ticks,
    but the second time is a fresh start).

    Args:
        previous: the state *before* this tick. active: (L,) bool, this tick's active leaves
            (or (N, n) state and (N, L) leaves of ``tick_rows``'s machines).
    """
    return active & ~previous.live[..., ct.leaf_ids]


def tick_sequence(
    ct: CompiledTree, state: BTState, leaf_status: jax.Array
) -> tuple[BTState, jax.Array, jax.Array, BTState]:
    """Ticks T times with ``lax.scan`` (scripted leaves, tests and tracing).

    Args:
        leaf_status: (T, L) int, row t = the leaves' statuses at tick t.

    Returns:
        final_state, root_status (T,) int32, active (T, L) bool, and ``trace``: the state after
        every tick, a ``BTState`` with (T, n) fields (``trace.node_status`` is the tick table).
    """

    def step(carry, row):
        carry, root, active = tick(ct, carry, row)
        return carry, (root, active, carry)

    final, (root, active, trace) = jax.lax.scan(step, state, jnp.asarray(leaf_status))
    return final, root, active, trace
