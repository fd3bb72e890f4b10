"""The compiled tick, pinned tick by tick with hand-written tables (py_trees style).

Each test scripts what every leaf would return at each tick and writes the expected status of
every node (R running, S success, F failure, - not ticked) as a table. The same table is checked
against the jitted compiled tick and the reference interpreter, so the tables specify the eBT
semantics of ``mjxskill/ebt/nodes.py`` for both.
"""

import textwrap

import jax
import numpy as np
import pytest

import mjxskill  # noqa: F401  (XLA flags before jax runs anything)
from mjxskill.bt_compiled import compile_tree, format_trace, init_state, started_leaves, tick, tick_sequence
from mjxskill.ebt import nodes as N
from mjxskill.ebt.interpreter import run_script

from bt_examples import push_tree

LETTER_STATUS = {"R": N.Status.RUNNING, "S": N.Status.SUCCESS, "F": N.Status.FAILURE}

# One jit for all tables: a tree is a static argument, so each structure compiles once.
jitted_sequence = jax.jit(tick_sequence, static_argnums=0)


def rows(table: str) -> list[list[str]]:
    return [line.split() for line in textwrap.dedent(table).strip().splitlines()]


def check_table(tree: N.Node, script: dict[str, str], expected: str) -> None:
    """script: leaf name -> one status letter per tick. expected: the trace table."""
    ct = compile_tree(tree)
    assert sorted(script) == sorted(leaf.name for leaf in ct.leaves), "script must cover every leaf"
    ticks = [rows(s)[0] for s in script.values()]
    assert len({len(t) for t in ticks}) == 1, "every leaf needs one status per tick"
    letters = np.array([rows(script[leaf.name])[0] for leaf in ct.leaves]).T  # (T, L)
    leaf_status = np.vectorize(lambda c: int(LETTER_STATUS[c]))(letters).astype(np.int32)

    _, root, active, trace = jitted_sequence(ct, init_state(ct), leaf_status)
    node_status = trace.node_status
    compiled = format_trace(ct, node_status)
    assert rows(compiled) == rows(expected), f"compiled tick:\n{compiled}"
    np.testing.assert_array_equal(root, np.asarray(node_status)[:, 0])
    np.testing.assert_array_equal(active, np.asarray(node_status)[:, ct.leaf_ids] != -1)

    results = run_script(tree, [list(map(N.Status, row)) for row in leaf_status.tolist()])
    reference = np.full(node_status.shape, -1)
    for t, result in enumerate(results):
        for nid, status in result.node_status.items():
            reference[t, nid] = int(status)
    interpreted = format_trace(ct, reference)
    assert rows(interpreted) == rows(expected), f"reference interpreter:\n{interpreted}"


def test_push_succeeds_then_restarts():
    # ParallelFs returns with its first finished child and does not tick the ones after it;
    # SerialStar does not re-tick ToStart once it succeeded; after SUCCESS the tree restarts.
    check_table(
        push_tree(),
        {
            "GoToStart": "R R S R R R R",
            "Stiffen1": "R R R R R R R",
            "GoToGoal": "R R R R S R R",
            "Stiffen2": "R R R R R R R",
            "Press": "R R R R R R R",
        },
        """
        Push          R R R R S R R
          ToStart     R R S - - R R
            GoToStart R R S - - R R
            Stiffen1  R R - - - R R
          PushToGoal  - - R R S - -
            GoToGoal  - - R R S - -
            Stiffen2  - - R R - - -
            Press     - - R R - - -
        """,
    )


def test_push_fails_and_restarts_from_the_first_block():
    check_table(
        push_tree(),
        {
            "GoToStart": "R S R R",
            "Stiffen1": "R R R R",
            "GoToGoal": "R R F R",
            "Stiffen2": "R R R R",
            "Press": "R R R R",
        },
        """
        Push          R R F R
          ToStart     R S - R
            GoToStart R S - R
            Stiffen1  R - - R
          PushToGoal  - R F -
            GoToGoal  - R F -
            Stiffen2  - R - -
            Press     - R - -
        """,
    )


GUARDED_SCRIPT = {"Safe": "S S F S", "Move": "R R R S"}


def test_sequence_rechecks_its_condition_every_tick():
    check_table(
        N.sequence("Guarded", N.condition("Safe"), N.action("Move")),
        GUARDED_SCRIPT,
        """
        Guarded R R F S
          Safe  S S F S
          Move  R R - S
        """,
    )


def test_serial_star_does_not_retick_succeeded_children():
    check_table(
        N.serial_star("Steps", N.condition("Safe"), N.action("Move")),
        GUARDED_SCRIPT,
        """
        Steps   R R R S
          Safe  S - - -
          Move  R R R S
        """,
    )


FALLBACK_SCRIPT = {"Try1": "F F S F", "Try2": "R R R S"}


def test_selector_retries_earlier_children_every_tick():
    check_table(
        N.selector("Fallback", N.action("Try1"), N.action("Try2")),
        FALLBACK_SCRIPT,
        """
        Fallback R R S S
          Try1   F F S F
          Try2   R R - S
        """,
    )


def test_selector_star_resumes_at_the_running_child():
    check_table(
        N.selector_star("FallbackStar", N.action("Try1"), N.action("Try2")),
        FALLBACK_SCRIPT,
        """
        FallbackStar R R R S
          Try1       F - - -
          Try2       R R R S
        """,
    )


def test_parallel_first_fail_skips_succeeded_children_and_fails_on_first_failure():
    check_table(
        N.parallel("All", N.action("a"), N.action("b"), N.action("c")),
        {"a": "S R R R S", "b": "R S R R S", "c": "R R R F S"},
        """
        All   R R R F S
          a   S - - - S
          b   R S - - S
          c   R R R F S
        """,
    )


def test_parallel_fs_preempts_a_serial_star_which_then_starts_afresh():
    check_table(
        N.parallel_fs("Race", N.serial_star("Steps", N.action("s1"), N.action("s2")), N.action("Watch")),
        {"s1": "S R R S S", "s2": "R R R R S", "Watch": "R F R R R"},
        """
        Race     R F R R S
          Steps  R R R R S
            s1   S - R S -
            s2   R R - R S
          Watch  R F R R -
        """,
    )


@pytest.mark.parametrize(
    "tree, script, expected",
    [
        (
            N.repeat(N.action("Wave"), 2, name="Twice"),
            {"Wave": "S R S S F"},
            """
            Twice   R R S R F
              Wave  S R S S F
            """,
        ),
        (
            N.retry(N.action("Grasp"), 2, name="Persist"),
            {"Grasp": "F R F F S"},
            """
            Persist  R R F R S
              Grasp  F R F F S
            """,
        ),
        (
            N.timeout(N.action("Reach"), 3, name="Deadline"),
            {"Reach": "R R R R S S"},
            """
            Deadline  R R F R S S
              Reach   R R R R S S
            """,
        ),
        (
            N.sequence(
                "Guard",
                N.inverter(N.condition("Blocked"), name="NotBlocked"),
                N.force_success(N.action("Wipe"), name="Optional"),
            ),
            {"Blocked": "F F S F", "Wipe": "R F R S"},
            """
            Guard         R S F S
              NotBlocked  S S F S
                Blocked   F F S F
              Optional    R S - S
                Wipe      R F - S
            """,
        ),
    ],
    ids=["repeat", "retry", "timeout", "inverter-force-success"],
)
def test_decorators(tree, script, expected):
    check_table(tree, script, expected)


def test_timeout_firing_halts_the_serial_star_below_it():
    check_table(
        N.timeout(N.serial_star("Two", N.action("p"), N.action("q")), 2, name="Limit"),
        {"p": "S R R S", "q": "R R R R"},
        """
        Limit   R F R F
          Two   R R R R
            p   S - R S
            q   R R - R
        """,
    )


def started_table(tree: N.Node, script: dict[str, str]) -> dict[str, str]:
    """leaf name -> per tick "x" where ``started_leaves`` says the leaf starts afresh."""
    ct = compile_tree(tree)
    letters = np.array([rows(script[leaf.name])[0] for leaf in ct.leaves]).T
    state = init_state(ct)
    marks = []
    for row in letters:
        previous = state
        state, _, active = tick(ct, state, np.array([int(LETTER_STATUS[c]) for c in row], np.int32))
        marks.append(np.asarray(started_leaves(ct, previous, active)))
    return {leaf.name: " ".join("x" if m else "." for m in np.stack(marks)[:, i]) for i, leaf in enumerate(ct.leaves)}


def test_started_leaves_mark_fresh_starts_not_continuations():
    # GoToStart runs on through ticks 2-3 (it was RUNNING), starts again after Push succeeded;
    # GoToGoal starts once, at tick 3.
    assert started_table(
        push_tree(),
        {
            "GoToStart": "R R S R R R R",
            "Stiffen1": "R R R R R R R",
            "GoToGoal": "R R R R S R R",
            "Stiffen2": "R R R R R R R",
            "Press": "R R R R R R R",
        },
    ) == {
        "GoToStart": "x . . . . x .",
        "Stiffen1": "x . . . . x .",
        "GoToGoal": ". . x . . . .",
        "Stiffen2": ". . x . . . .",
        "Press": ". . x . . . .",
    }
    # Repeat restarts its child after each success although the child is ticked every tick.
    assert started_table(N.repeat(N.action("Wave"), 2), {"Wave": "S R S S F"}) == {"Wave": "x x . x x"}
