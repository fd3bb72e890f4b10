"""compile_tree: the eBT as pre-order arrays plus the leaf table, written out by hand."""

import numpy as np
import pytest

import mjxskill  # noqa: F401  (XLA flags before jax runs anything)
from mjxskill.bt_compiled import compile_tree, format_trace
from mjxskill.ebt import nodes as N

from bt_examples import GOAL_OFFSETS, START_OFFSETS, STIFFNESS, press, push_tree

K = N.Kind
FORCE = press()  # apply_force arguments of the default push_tree


def test_push_tree_arrays():
    ct = compile_tree(push_tree())
    #            Push ToStart GoToStart Stiffen1 PushToGoal GoToGoal Stiffen2 Press
    np.testing.assert_array_equal(
        ct.kind, [K.SERIAL_STAR, K.PARALLEL_FS, K.ACTION, K.ACTION, K.PARALLEL_FS, K.ACTION, K.ACTION, K.ACTION]
    )
    np.testing.assert_array_equal(ct.parent, [-1, 0, 1, 1, 0, 4, 4, 4])
    np.testing.assert_array_equal(
        ct.child_table,
        [[1, 4, -1], [2, 3, -1], [-1] * 3, [-1] * 3, [5, 6, 7], [-1] * 3, [-1] * 3, [-1] * 3],
    )
    np.testing.assert_array_equal(ct.child_count, [2, 2, 0, 0, 3, 0, 0, 0])
    np.testing.assert_array_equal(ct.count, [0] * 8)
    np.testing.assert_array_equal(ct.leaf_ids, [2, 3, 5, 6, 7])
    np.testing.assert_array_equal(ct.leaf_index, [-1, -1, 0, 1, -1, 2, 3, 4])
    assert ct.names == ("Push", "ToStart", "GoToStart", "Stiffen1", "PushToGoal", "GoToGoal", "Stiffen2", "Press")
    assert (ct.num_nodes, ct.num_leaves) == (8, 5)
    assert ct.children(4) == (5, 6, 7)
    assert all(a.dtype == np.int32 and not a.flags.writeable for a in (ct.kind, ct.parent, ct.child_table, ct.count))


def test_push_leaf_table():
    ct = compile_tree(push_tree())
    assert ct.primitives == ("go_to_linear_offset", "change_stiffness", "apply_force")
    expected = [
        (2, K.ACTION, "GoToStart", "go_to_linear_offset", 0, {}, START_OFFSETS),
        (3, K.ACTION, "Stiffen1", "change_stiffness", 1, STIFFNESS, {}),
        (5, K.ACTION, "GoToGoal", "go_to_linear_offset", 0, {}, GOAL_OFFSETS),
        (6, K.ACTION, "Stiffen2", "change_stiffness", 1, STIFFNESS, {}),
        (7, K.ACTION, "Press", "apply_force", 2, FORCE, {}),
    ]
    assert [tuple(leaf) for leaf in ct.leaves] == expected


def test_counts_of_decorators():
    tree = N.sequence("s", N.repeat(N.action("a"), 3), N.retry(N.condition("c"), 2), N.timeout(N.action("b"), 50))
    ct = compile_tree(tree)
    np.testing.assert_array_equal(ct.count, [0, 3, 0, 2, 0, 50, 0])
    np.testing.assert_array_equal(ct.kind[ct.leaf_ids], [K.ACTION, K.CONDITION, K.ACTION])


def test_equality_and_hash_follow_structure_not_leaf_programs():
    # Equal structure -> equal static jit argument -> one compiled tick.
    a, b = compile_tree(push_tree()), compile_tree(push_tree(force_z=-3.0))
    assert a == b and hash(a) == hash(b)
    assert a.leaves != b.leaves
    different_count = compile_tree(N.repeat(N.action("a"), 2))
    assert different_count != compile_tree(N.repeat(N.action("a"), 3))
    # same kinds in pre-order, different shape: ((A), A) vs ((A, A))
    flat = compile_tree(N.sequence("s", N.sequence("t", N.action("a")), N.action("b")))
    nested = compile_tree(N.sequence("s", N.sequence("t", N.action("a"), N.action("b"))))
    np.testing.assert_array_equal(flat.kind, nested.kind)
    assert flat != nested


def test_parallel_with_more_than_31_children_is_rejected():
    with pytest.raises(ValueError, match=r"PARALLEL node 0 \('wide'\) has 32 children.*at most 31"):
        compile_tree(N.parallel("wide", *[N.action(f"a{i}") for i in range(32)]))
    # first-success parallels keep no per-child memory, so they have no such limit
    assert compile_tree(N.parallel_fs("wide", *[N.action(f"a{i}") for i in range(40)])).num_leaves == 40


def test_compile_tree_rejects_non_nodes():
    with pytest.raises(TypeError, match="expects an mjxskill.ebt.nodes.Node, got dict"):
        compile_tree({"kind": "sequence"})


def test_format_trace_table():
    ct = compile_tree(N.parallel_fs("Race", N.action("a"), N.timeout(N.action("b"), 2, name="t")))
    table = format_trace(ct, np.array([[0, 0, 0, 0], [1, 1, -1, -1]]), symbols=True)
    assert table.splitlines() == [
        "||FS Race  R S",
        "  A a      R S",
        "  t2 t     R -",
        "    A b    R -",
    ]
    with pytest.raises(ValueError, match=r"shape \(T, 4\), got \(4,\)"):
        format_trace(ct, np.zeros(4))
