"""Property: the compiled tick does what the reference interpreter does, tick by tick.

Random trees (every node kind, depth up to 5, up to 8 children) and random leaf-status scripts;
root status, every node's status, the active leaves and the halting rule's "live" nodes (hence
the leaves that start afresh) must agree at every tick.

Cost: a jit compiles once per tree structure (about 1 s for 25 nodes on the 2-core CPU), while
running ``tick`` eagerly costs about 15 ms per tick, so most examples run the un-jitted tick
(the same code path, op by op); a few examples jit ``tick_sequence`` (lax.scan over ticks)
vmapped over a batch of scripts, which checks the traced program on random trees too.
"""

import itertools

import jax
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mjxskill  # noqa: F401  (XLA flags before jax runs anything)
from mjxskill.bt_compiled import (compile_tree, format_trace, init_rows, init_state, started_leaves, tick, tick_rows,
                                  tick_sequence)
from mjxskill.ebt import nodes as N
from mjxskill.ebt.interpreter import Interpreter, run_script

MAX_DEPTH = 5
MAX_CHILDREN = 8
COUNTED = (N.Kind.REPEAT, N.Kind.RETRY, N.Kind.TIMEOUT)
INNER_KINDS = sorted(N.COMPOSITES | N.DECORATORS)
# Actions twice as likely as conditions: only actions run, which is what exercises memory.
LEAF_KINDS = [N.Kind.ACTION, N.Kind.ACTION, N.Kind.CONDITION]


@st.composite
def trees(draw, max_depth: int = MAX_DEPTH, max_nodes: int = 30) -> N.Node:
    """Random eBTs over every node kind; node names are unique ("n<pre-order id>")."""
    budget = [max_nodes]
    ids = itertools.count()

    def build(depth: int) -> N.Node:
        name = f"n{next(ids)}"
        budget[0] -= 1
        if depth >= max_depth or budget[0] <= 0:
            kind = draw(st.sampled_from(LEAF_KINDS))
        elif depth == 1:  # a lone leaf is not worth an example
            kind = draw(st.sampled_from(INNER_KINDS))
        else:
            kind = draw(st.sampled_from(INNER_KINDS + LEAF_KINDS))
        if kind in N.LEAVES:
            return N.Node(kind, name, primitive=name)
        if kind in N.DECORATORS:
            count = draw(st.integers(1, 3)) if kind in COUNTED else 0
            return N.Node(kind, name, (build(depth + 1),), count=count)
        n_children = draw(st.integers(1, MAX_CHILDREN))
        children = [build(depth + 1)]
        while len(children) < n_children and budget[0] > 0:
            children.append(build(depth + 1))
        return N.Node(kind, name, tuple(children))

    return build(1)


def scripts(tree: N.Node, min_ticks: int = 8, max_ticks: int = 25):
    """(T, L) statuses per tick and leaf; conditions only SUCCESS/FAILURE."""
    per_leaf = [
        st.sampled_from([0, 1, 2]) if leaf.kind == N.Kind.ACTION else st.sampled_from([1, 2])
        for leaf in tree.leaves()
    ]
    return st.lists(st.tuples(*per_leaf), min_size=min_ticks, max_size=max_ticks)


def reference_trace(tree: N.Node, leaf_status: np.ndarray):
    """Interpreter results as arrays: root (T,), node_status (T, n) with -1, active (T, L),
    live (T, n): ticked and RUNNING together with all ancestors (the halting rule)."""
    results = run_script(tree, [[N.Status(s) for s in row] for row in leaf_status.tolist()])
    interp = Interpreter(tree)
    parent = {child: nid for nid, kids in enumerate(interp.children) for child in kids}
    leaf_ids = [i for i, node in enumerate(interp.nodes) if node.is_leaf]
    ticks, n = len(results), len(interp.nodes)
    node_status = np.full((ticks, n), -1, np.int32)
    active = np.zeros((ticks, len(leaf_ids)), bool)
    live = np.zeros((ticks, n), bool)
    for t, result in enumerate(results):
        for nid, status in result.node_status.items():
            node_status[t, nid] = int(status)
        active[t] = np.isin(leaf_ids, result.active_leaves)
        for nid in range(n):  # pre-order: the parent's flag is already set
            live[t, nid] = node_status[t, nid] == N.Status.RUNNING and (nid == 0 or live[t, parent[nid]])
    root = np.array([int(r.status) for r in results], np.int32)
    return root, node_status, active, live


def assert_same_trace(ct, leaf_status, root, node_status, active, live, reference):
    ref_root, ref_status, ref_active, ref_live = reference
    message = (
        f"tree:\n{N.render(ct.tree)}\nleaf statuses (T, L):\n{leaf_status}\n"
        f"compiled:\n{format_trace(ct, node_status)}\nreference:\n{format_trace(ct, ref_status)}"
    )
    np.testing.assert_array_equal(np.asarray(node_status), ref_status, err_msg=message)
    np.testing.assert_array_equal(np.asarray(root), ref_root, err_msg=message)
    np.testing.assert_array_equal(np.asarray(active), ref_active, err_msg=message)
    np.testing.assert_array_equal(np.asarray(live), ref_live, err_msg=message)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_eager_tick_matches_reference_interpreter(data):
    tree = data.draw(trees(), label="tree")
    leaf_status = np.array(data.draw(scripts(tree), label="script"), np.int32).reshape(-1, len(tree.leaves()))
    ct = compile_tree(tree)
    # pre-order numbering agrees with the interpreter's
    interp = Interpreter(tree)
    assert [list(ct.children(i)) for i in range(ct.num_nodes)] == interp.children

    state = init_state(ct)
    roots, statuses, actives, lives, starts = [], [], [], [], []
    for row in leaf_status:
        previous = state
        state, root, active = tick(ct, state, row)
        roots.append(root)
        statuses.append(state.node_status)
        actives.append(active)
        lives.append(state.live)
        starts.append(started_leaves(ct, previous, active))
    reference = reference_trace(tree, leaf_status)
    assert_same_trace(ct, leaf_status, roots, np.stack(statuses), np.stack(actives), np.stack(lives), reference)
    # a leaf starts afresh when ticked without having been live (running on) after the last tick
    _, _, ref_active, ref_live = reference
    was_live = np.vstack([np.zeros((1, ct.num_nodes), bool), ref_live[:-1]])[:, ct.leaf_ids]
    np.testing.assert_array_equal(np.stack(starts), ref_active & ~was_live)


BATCH = 16
jitted_batch_sequence = jax.jit(jax.vmap(tick_sequence, in_axes=(None, 0, 0)), static_argnums=0)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tree=trees(max_nodes=20), seed=st.integers(0, 2**31 - 1))
def test_jitted_vmapped_sequence_matches_reference_interpreter(tree, seed):
    ct = compile_tree(tree)
    rng = np.random.default_rng(seed)
    ticks = 15
    leaf_status = rng.integers(0, 3, size=(BATCH, ticks, ct.num_leaves), dtype=np.int32)
    is_condition = ct.kind[ct.leaf_ids] == N.Kind.CONDITION
    leaf_status[..., is_condition] = rng.integers(1, 3, size=leaf_status[..., is_condition].shape)
    states = jax.vmap(lambda _: init_state(ct))(np.arange(BATCH))

    _, root, active, trace = jitted_batch_sequence(ct, states, leaf_status)
    for b in range(BATCH):
        reference = reference_trace(tree, leaf_status[b])
        assert_same_trace(ct, leaf_status[b], root[b], trace.node_status[b], active[b], trace.live[b], reference)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tree=trees(max_nodes=25), seed=st.integers(0, 2**31 - 1))
def test_rows_tick_matches_reference_interpreter(tree, seed):
    """The numpy tick over a batch of machines (what a native batch's rows run) does, row by row,
    what the reference interpreter does with that row's script; started leaves as well."""
    ct = compile_tree(tree)
    rng = np.random.default_rng(seed)
    rows, ticks = 6, 15
    leaf_status = rng.integers(0, 3, size=(rows, ticks, ct.num_leaves), dtype=np.int32)
    is_condition = ct.kind[ct.leaf_ids] == N.Kind.CONDITION
    leaf_status[..., is_condition] = rng.integers(1, 3, size=leaf_status[..., is_condition].shape)
    state = init_rows(ct, rows)
    root, node_status, active, live, started = [], [], [], [], []
    for t in range(ticks):
        new, r, a = tick_rows(ct, state, leaf_status[:, t])
        started.append(started_leaves(ct, state, a))
        state = new
        root.append(r), node_status.append(new.node_status), active.append(a), live.append(new.live)
    root, node_status, active, live, started = (np.stack(x, axis=1) for x in (root, node_status, active, live, started))
    for b in range(rows):
        reference = reference_trace(tree, leaf_status[b])
        assert_same_trace(ct, leaf_status[b], root[b], node_status[b], active[b], live[b], reference)
        was_live = np.concatenate([np.zeros((1, ct.num_nodes), bool), reference[3][:-1]])[:, ct.leaf_ids]
        np.testing.assert_array_equal(started[b], reference[2] & ~was_live)


def test_rows_tick_refuses_what_it_cannot_run():
    ct = compile_tree(N.Node(N.Kind.SEQUENCE, "s", (N.Node(N.Kind.ACTION, "a", primitive="a"),)))
    state = init_rows(ct, 3)
    with pytest.raises(ValueError, match=r"needs \(N, 1\)"):
        tick_rows(ct, state, np.zeros(1, np.int32))
    with pytest.raises(ValueError, match="must be bool"):
        tick_rows(ct, state._replace(live=state.live.astype(np.int32)), np.zeros((3, 1), np.int32))
    with pytest.raises(ValueError, match=r"this tree needs \(2, 2\)"):  # 3 machines' state, 2 rows of statuses
        tick_rows(ct, state, np.zeros((2, 1), np.int32))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tree=trees(max_nodes=12), seed=st.integers(0, 2**31 - 1))
def test_rows_tick_reads_out_of_range_statuses_as_the_jax_tick_does(tree, seed):
    """Leaf statuses outside RUNNING/SUCCESS/FAILURE (a Condition's RUNNING among them) count as
    FAILURE in the rows' compiled program as in ``tick``, which the interpreter cannot be asked
    about (it raises): the two compiled ticks give the same states, roots and active leaves."""
    ct = compile_tree(tree)
    rng = np.random.default_rng(seed)
    rows, ticks = 3, 6
    leaf_status = rng.integers(-2, 5, size=(rows, ticks, ct.num_leaves), dtype=np.int32)
    state, vmapped = init_rows(ct, rows), jax.vmap(lambda s, l: tick(ct, s, l))
    jax_state = jax.tree.map(np.asarray, jax.vmap(lambda _: init_state(ct))(np.arange(rows)))
    for t in range(ticks):
        state, root, active = tick_rows(ct, state, leaf_status[:, t])
        jax_state, jax_root, jax_active = jax.tree.map(np.asarray, vmapped(jax_state, leaf_status[:, t]))
        for got, want in zip(state, jax_state):
            np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(root, jax_root)
        np.testing.assert_array_equal(active, jax_active)
