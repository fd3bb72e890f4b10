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

Out-of-range leaf statuses: an Action's value other than RUNNING (0) or SUCCESS (1) counts as
FAILURE. A Condition returning RUNNING is an error in the interpreter, but a jitted function
cannot raise, so a Condition's value other than SUCCESS counts as FAILURE.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from mjxskill.bt_compiled.compile import CompiledTree
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

    memory: jax.Array
    node_status: jax.Array
    live: jax.Array


def init_state(ct: CompiledTree) -> BTState:
    """A fresh state machine: all memory 0, nothing ticked yet."""
    n = ct.num_nodes
    return BTState(
        memory=jnp.zeros(n, jnp.int32),
        node_status=jnp.full(n, NOT_TICKED, jnp.int32),
        live=jnp.zeros(n, jnp.bool_),
    )


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
    if leaf_status.shape != (ct.num_leaves,):
        raise ValueError(
            f"leaf_status has shape {leaf_status.shape}; this tree has {ct.num_leaves} leaves, so it "
            f"must be ({ct.num_leaves},) (use jax.vmap for batches)"
        )
    if not jnp.issubdtype(leaf_status.dtype, jnp.integer):
        raise ValueError(f"leaf_status must hold integer Status values, got dtype {leaf_status.dtype}")
    for field, value in zip(state._fields, state):
        if value.shape != (ct.num_nodes,):
            raise ValueError(f"state.{field} has shape {value.shape}; this tree needs ({ct.num_nodes},)")
    # One vectorised pass maps out-of-range values to FAILURE (see the module docstring).
    leaf_status = leaf_status.astype(jnp.int32)
    is_condition = ct.kind[ct.leaf_ids] == int(Kind.CONDITION)
    valid = jnp.where(is_condition, leaf_status == SUCCESS, (leaf_status == SUCCESS) | (leaf_status == RUNNING))
    leaf_status = jnp.where(valid, leaf_status, FAILURE)
    memory = state.memory.astype(jnp.int32)

    n = ct.num_nodes
    enabled: list = [None] * n  # traced bool per node: ticked this tick
    status: list = [None] * n  # traced int32 per node: valid where enabled
    new_memory: list = [None] * n  # traced int32 per node, before halting

    def visit(nid: int, on) -> jax.Array:
        kind = Kind(int(ct.kind[nid]))
        kids = ct.children(nid)
        mem = memory[nid] if kind in _KINDS_WITH_MEMORY else None
        new_mem = 0

        if kind in (Kind.ACTION, Kind.CONDITION):
            out = leaf_status[int(ct.leaf_index[nid])]
        elif kind in (Kind.SEQUENCE, Kind.SERIAL_STAR, Kind.SELECTOR, Kind.SELECTOR_STAR):
            # Sequences go on while children succeed, selectors while they fail; the starred
            # kinds resume from the child that was running (children before it count as done).
            go_on = SUCCESS if kind in (Kind.SEQUENCE, Kind.SERIAL_STAR) else FAILURE
            has_memory = kind in (Kind.SERIAL_STAR, Kind.SELECTOR_STAR)
            going = on
            out = go_on
            for i, cid in enumerate(kids):
                child_on = going & (mem <= i) if has_memory else going
                s = visit(cid, child_on)
                stop = child_on & (s != go_on)
                out = jnp.where(stop, s, out)
                if has_memory:
                    new_mem = jnp.where(stop & (s == RUNNING), i, new_mem)
                going = going & ~stop
        elif kind == Kind.PARALLEL:
            done = mem
            going = on
            failed = False
            running = False
            for i, cid in enumerate(kids):
                child_on = going & (((done >> i) & 1) == 0)
                s = visit(cid, child_on)
                failed = failed | (child_on & (s == FAILURE))
                running = running | (child_on & (s == RUNNING))
                done = jnp.where(child_on & (s == SUCCESS), done | (1 << i), done)
                going = going & ~failed  # the children after a failure are not ticked
            out = jnp.where(failed, FAILURE, jnp.where(running, RUNNING, SUCCESS))
            new_mem = done
        elif kind == Kind.PARALLEL_FS:
            going = on
            out = RUNNING
            for cid in kids:
                s = visit(cid, going)
                stop = going & (s != RUNNING)
                out = jnp.where(stop, s, out)
                going = going & ~stop
        elif kind == Kind.INVERTER:
            s = visit(kids[0], on)
            out = jnp.where(s == SUCCESS, FAILURE, jnp.where(s == FAILURE, SUCCESS, s))
        elif kind == Kind.FORCE_SUCCESS:
            s = visit(kids[0], on)
            out = jnp.where(s == FAILURE, SUCCESS, s)
        elif kind in (Kind.REPEAT, Kind.RETRY):
            # Repeat counts successes, Retry failures; below n, the node restarts its (finished)
            # child on the next tick and reports RUNNING.
            counted = SUCCESS if kind == Kind.REPEAT else FAILURE
            s = visit(kids[0], on)
            runs = mem + 1
            restart = (s == counted) & (runs < int(ct.count[nid]))
            out = jnp.where(restart, RUNNING, s)
            new_mem = jnp.where(restart, runs, mem)
        elif kind == Kind.TIMEOUT:
            ticks = mem + 1
            s = visit(kids[0], on)
            fire = (s == RUNNING) & (ticks >= int(ct.count[nid]))
            out = jnp.where(fire, FAILURE, s)
            new_mem = ticks
        else:  # pragma: no cover - Kind is closed
            raise AssertionError(kind)

        enabled[nid] = on
        status[nid] = jnp.asarray(out, jnp.int32)
        new_memory[nid] = jnp.asarray(new_mem, jnp.int32)
        return status[nid]

    root_status = visit(0, jnp.bool_(True))

    # Halting: a node keeps its memory only if it was ticked and it and all its ancestors
    # returned RUNNING. Parents come before children in pre-order, so one pass suffices.
    live_flags: list = [None] * n
    for nid in range(n):
        parent_live = jnp.bool_(True) if ct.parent[nid] < 0 else live_flags[int(ct.parent[nid])]
        live_flags[nid] = parent_live & enabled[nid] & (status[nid] == RUNNING)

    live = jnp.stack(live_flags)
    new_state = BTState(
        memory=jnp.where(live, jnp.stack(new_memory), 0),
        node_status=jnp.where(jnp.stack(enabled), jnp.stack(status), NOT_TICKED),
        live=live,
    )
    active = jnp.stack([enabled[int(nid)] for nid in ct.leaf_ids])
    return new_state, root_status, active


def started_leaves(ct: CompiledTree, previous: BTState, active: jax.Array) -> jax.Array:
    """(L,) bool: leaves ticked this tick that were not running on from the last one.

    A leaf program with internal state (a motion generator's trajectory start, a spiral's
    phase) must restart for these: the leaf is new, was halted, finished, or sits under a node
    that finished (e.g. a Repeat restarting its child ticks the same leaf in consecutive ticks,
    but the second time is a fresh start).

    Args:
        previous: the state *before* this tick. active: (L,) bool, this tick's active leaves.
    """
    return active & ~previous.live[ct.leaf_ids]


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
