"""The compiled tick under jit and vmap: no retracing, batches equal separate runs, bad input.

One fixed tree uses every node kind at depth 5 (ALL_KINDS_TREE); jitted functions are shared
through module-scoped fixtures so each structure compiles once.
"""

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import mjxskill  # noqa: F401  (XLA flags before jax runs anything)
from mjxskill.bt_compiled import compile_tree, init_state, tick
from mjxskill.ebt import nodes as N
from mjxskill.ebt.interpreter import Interpreter

from bt_examples import push_tree

R, S, F = int(N.Status.RUNNING), int(N.Status.SUCCESS), int(N.Status.FAILURE)

ALL_KINDS_TREE = N.serial_star(
    "root",
    N.selector(
        "pick",
        N.inverter(N.condition("c0"), name="not_c0"),
        N.sequence("seq", N.condition("c1"), N.timeout(N.action("a1"), 3, name="t3")),
    ),
    N.parallel(
        "par",
        N.repeat(N.action("a2"), 2, name="rep2"),
        N.retry(N.selector_star("sel_star", N.action("a3"), N.action("a4")), 2, name="retry2"),
        N.parallel_fs("race", N.force_success(N.action("a5"), name="force"), N.condition("c2")),
    ),
    N.action("a6"),
)


def random_scripts(ct, batch: int, ticks: int, seed: int) -> np.ndarray:
    """(batch, ticks, L) leaf statuses, RUNNING-heavy for actions, none for conditions."""
    rng = np.random.default_rng(seed)
    status = rng.choice([R, R, S, F], size=(batch, ticks, ct.num_leaves)).astype(np.int32)
    is_condition = ct.kind[ct.leaf_ids] == N.Kind.CONDITION
    status[..., is_condition] = rng.choice([S, F], size=status[..., is_condition].shape)
    return status


def test_all_kinds_tree_covers_every_kind_at_depth_5():
    assert {node.kind for node in ALL_KINDS_TREE.walk()} == set(N.Kind)
    assert ALL_KINDS_TREE.depth() == 5


@pytest.fixture(scope="module")
def counted_tick():
    """jit(tick) with the tree static; chex counts the traces."""
    chex.clear_trace_counter()
    return jax.jit(chex.assert_max_traces(tick, n=1), static_argnums=0)


def test_jitted_tick_traces_once_across_ticks_and_equal_trees(counted_tick):
    scripts = random_scripts(compile_tree(push_tree()), batch=1, ticks=12, seed=0)[0]
    # A fresh compile of the same tree, and one whose leaves only differ in args, are equal
    # static arguments: neither may trigger a second trace (chex raises if one does).
    for ct in (compile_tree(push_tree()), compile_tree(push_tree()), compile_tree(push_tree(force_z=-3.0))):
        state = init_state(ct)
        for row in scripts:
            state, root, active = counted_tick(ct, state, row)
        assert root.shape == () and root.dtype == jnp.int32
        assert active.shape == (ct.num_leaves,) and active.dtype == jnp.bool_


@pytest.fixture(scope="module")
def all_kinds():
    ct = compile_tree(ALL_KINDS_TREE)
    one = jax.jit(lambda state, leaf_status: tick(ct, state, leaf_status))
    batched = jax.jit(jax.vmap(lambda state, leaf_status: tick(ct, state, leaf_status)))
    return ct, one, batched


def test_vmapped_batch_of_64_equals_64_separate_runs_and_the_interpreter(all_kinds):
    ct, one, batched = all_kinds
    batch, ticks = 64, 12
    scripts = random_scripts(ct, batch, ticks, seed=1)
    batch_state = jax.vmap(lambda _: init_state(ct))(np.arange(batch))
    states = [init_state(ct) for _ in range(batch)]
    interpreters = [Interpreter(ALL_KINDS_TREE) for _ in range(batch)]
    leaf_ids = ct.leaf_ids.tolist()
    finished = 0
    for t in range(ticks):
        batch_state, batch_root, batch_active = batched(batch_state, scripts[:, t])
        for b in range(batch):
            states[b], root, active = one(states[b], scripts[b, t])
            np.testing.assert_array_equal(batch_root[b], root)
            np.testing.assert_array_equal(batch_active[b], active)
            chex.assert_trees_all_equal(jax.tree.map(lambda x: x[b], batch_state), states[b])

            table = dict(zip(leaf_ids, scripts[b, t].tolist()))
            result = interpreters[b].tick(lambda nid, node: N.Status(table[nid]))
            assert int(root) == int(result.status)
            expected_active = [leaf_ids.index(i) for i in result.active_leaves]
            np.testing.assert_array_equal(np.flatnonzero(np.asarray(active)), expected_active)
            finished += int(root) != R
    assert finished > 0, "the scripts should drive some machines to a finish"


def test_out_of_range_leaf_statuses_count_as_failure():
    # A condition returning RUNNING is an error in the interpreter; the jitted tick cannot
    # raise, so it counts as FAILURE, like any value an action cannot return.
    for leaf, raw, expected in [
        (N.condition("c"), R, F),
        (N.condition("c"), 7, F),
        (N.condition("c"), S, S),
        (N.action("a"), 7, F),
        (N.action("a"), -1, F),
        (N.action("a"), R, R),
        (N.action("a"), S, S),
    ]:
        ct = compile_tree(leaf)
        _, root, _ = tick(ct, init_state(ct), np.array([raw], np.int32))
        assert int(root) == expected, (leaf.kind.name, raw)


def test_bad_leaf_status_and_state_raise_clear_errors():
    ct = compile_tree(push_tree())
    state = init_state(ct)
    with pytest.raises(ValueError, match=r"shape \(4,\).*5 leaves"):
        tick(ct, state, np.zeros(4, np.int32))
    with pytest.raises(ValueError, match="use jax.vmap"):
        tick(ct, state, np.zeros((2, 5), np.int32))
    with pytest.raises(ValueError, match="integer Status values.*float32"):
        tick(ct, state, np.zeros(5, np.float32))
    other = init_state(compile_tree(ALL_KINDS_TREE))
    with pytest.raises(ValueError, match=r"state.memory has shape \(20,\); this tree needs \(8,\)"):
        tick(ct, other, np.zeros(5, np.int32))


def test_parallel_memory_bitmask_holds_31_children():
    tree = N.parallel("wide", *[N.action(f"a{i}") for i in range(31)])
    ct = compile_tree(tree)
    # Tick 1: all but the last succeed. Tick 2: only the last is ticked again, and succeeds.
    state, root, active = tick(ct, init_state(ct), np.array([S] * 30 + [R], np.int32))
    assert int(root) == R and bool(active.all())
    assert int(state.memory[0]) == 2**30 - 1
    state, root, active = tick(ct, state, np.full(31, S, np.int32))
    assert int(root) == S
    np.testing.assert_array_equal(active, [False] * 30 + [True])
