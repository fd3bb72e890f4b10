"""The eBT processors' semantics, pinned py_trees-style.

Every leaf is a scripted status queue: each time the leaf is ticked it returns the next letter
of its script (R running, S success, F failure). Each test writes the expected status of every
node at every tick ("." = not ticked this tick) and asserts the whole table, and that every
scripted status was used, i.e. every leaf was ticked exactly as often as the table says.

Which semantics each processor has (see mjxskill/ebt/nodes.py):
``->`` Sequence: no memory (py_trees memory=False, SkiROS Serial). ``->*`` SerialStar: memory
(py_trees memory=True, BehaviorTree.CPP Sequence). ``?`` / ``?*``: fallback without / with
memory. ``||FF`` Parallel: succeeded children are not re-ticked; the first failure wins.
``||FS`` ParallelFs: the first child to finish decides; the others are halted.
"""

import pytest

from mjxskill.ebt import nodes as bt
from mjxskill.ebt.interpreter import Interpreter, run_script
from mjxskill.ebt.nodes import Status

LETTER = {Status.RUNNING: "R", Status.SUCCESS: "S", Status.FAILURE: "F"}
STATUS = {v: k for k, v in LETTER.items()}


def status_table(tree: bt.Node, scripts: dict[str, str], ticks: int) -> dict[str, list[str]]:
    """node name -> status letter per tick, ticking ``tree`` with scripted leaves."""
    queues = {name: list(script) for name, script in scripts.items()}
    interp = Interpreter(tree)
    names = [node.name for node in interp.nodes]
    assert len(set(names)) == len(names), "table rows need unique node names"
    rows = {name: [] for name in names}

    def leaf(node_id, node):
        return STATUS[queues[node.name].pop(0)]

    for _ in range(ticks):
        result = interp.tick(leaf)
        # Leaves are reported in tick order, which for these trees is pre-order.
        assert list(result.active_leaves) == sorted(result.active_leaves)
        for node_id, name in enumerate(names):
            status = result.node_status.get(node_id)
            rows[name].append(LETTER[status] if status is not None else ".")
    unused = {name: "".join(q) for name, q in queues.items() if q}
    assert not unused, f"scripted statuses never used: {unused}"
    return rows


def assert_table(tree: bt.Node, scripts: dict[str, str], expected: str) -> None:
    lines = [line.split() for line in expected.strip().splitlines()]
    ticks = len(lines[0]) - 1
    want = {row[0]: row[1:] for row in lines[1:]}
    got = status_table(tree, scripts, ticks)

    def text(rows):
        return "\n".join(f"{name:<6} {' '.join(values)}" for name, values in rows.items())

    assert text(got) == text(want)


a, b, c, d, e = (bt.action(name) for name in "abcde")


def test_sequence_reticks_every_child_from_the_first():
    assert_table(
        bt.sequence("root", a, b),
        {"a": "SSS", "b": "RRS"},
        """
        tick 1 2 3
        root R R S
        a    S S S
        b    R R S
        """,
    )


def test_sequence_stops_at_the_first_failure():
    assert_table(
        bt.sequence("root", a, b),
        {"a": "SF", "b": "R"},
        """
        tick 1 2
        root R F
        a    S F
        b    R .
        """,
    )


def test_serial_star_remembers_successes_until_it_finishes():
    # Tick 4: the root finished at tick 3, so it starts afresh and ticks a again.
    assert_table(
        bt.serial_star("root", a, b),
        {"a": "SS", "b": "RRSR"},
        """
        tick 1 2 3 4
        root R R S R
        a    S . . S
        b    R R S R
        """,
    )


def test_serial_star_fails_at_the_first_failure():
    assert_table(
        bt.serial_star("root", a, b, c),
        {"a": "S", "b": "RF", "c": ""},
        """
        tick 1 2
        root R F
        a    S .
        b    R F
        c    . .
        """,
    )


def test_sequence_retick_halts_a_later_running_child():
    # Tick 2: a runs again, so the SerialStar behind it is not ticked: it is halted and forgets
    # that c succeeded; at tick 3 it starts over at c.
    star = bt.serial_star("star", c, d)
    assert_table(
        bt.sequence("root", a, star),
        {"a": "SRS", "c": "SS", "d": "RS"},
        """
        tick 1 2 3
        root R R S
        a    S R S
        star R . S
        c    S . S
        d    R . S
        """,
    )


def test_selector_reticks_from_the_first_child():
    assert_table(
        bt.selector("root", a, b),
        {"a": "FFS", "b": "RS"},
        """
        tick 1 2 3
        root R S S
        a    F F S
        b    R S .
        """,
    )


def test_selector_fails_when_every_child_fails():
    assert_table(
        bt.selector("root", a, b),
        {"a": "F", "b": "F"},
        """
        tick 1
        root F
        a    F
        b    F
        """,
    )


def test_selector_star_remembers_failures_until_it_finishes():
    assert_table(
        bt.selector_star("root", a, b),
        {"a": "FF", "b": "RRSR"},
        """
        tick 1 2 3 4
        root R R S R
        a    F . . F
        b    R R S R
        """,
    )


def test_parallel_does_not_retick_children_that_succeeded():
    assert_table(
        bt.parallel("root", a, b, c),
        {"a": "RS", "b": "S", "c": "RRS"},
        """
        tick 1 2 3
        root R R S
        a    R S .
        b    S . .
        c    R R S
        """,
    )


def test_parallel_first_failure_halts_the_others():
    # Tick 2: a fails, so the root fails without ticking star and e; both are halted, and at
    # tick 3 star starts over at c.
    star = bt.serial_star("star", c, d)
    assert_table(
        bt.parallel("root", a, star, e),
        {"a": "RFR", "c": "SS", "d": "RR", "e": "RR"},
        """
        tick 1 2 3
        root R F R
        a    R F R
        star R . R
        c    S . S
        d    R . R
        e    R . R
        """,
    )


def test_parallel_fs_first_finisher_decides_and_preempts_the_rest():
    # Tick 2: star keeps its memory (c is skipped) while everything runs; e succeeds, the root
    # returns SUCCESS and halts star. Tick 3: star starts over at c. Tick 4: a finishes first,
    # so star and e are not even ticked.
    star = bt.serial_star("star", c, d)
    assert_table(
        bt.parallel_fs("root", a, star, e),
        {"a": "RRRS", "c": "SS", "d": "RRR", "e": "RSR"},
        """
        tick 1 2 3 4
        root R S R S
        a    R R R S
        star R R R .
        c    S . S .
        d    R R R .
        e    R S R .
        """,
    )


def test_parallel_fs_returns_a_failure_too():
    assert_table(
        bt.parallel_fs("root", a, b),
        {"a": "RF", "b": "R"},
        """
        tick 1 2
        root R F
        a    R F
        b    R .
        """,
    )


def test_inverter_swaps_success_and_failure():
    assert_table(
        bt.inverter(a, name="root"),
        {"a": "RSF"},
        """
        tick 1 2 3
        root R F S
        a    R S F
        """,
    )


def test_force_success_turns_failure_into_success():
    assert_table(
        bt.force_success(a, name="root"),
        {"a": "RFS"},
        """
        tick 1 2 3
        root R S S
        a    R F S
        """,
    )


def test_repeat_restarts_its_child_after_each_success():
    # The child (a SerialStar) finishes at ticks 2 and 3 and starts afresh each time.
    star = bt.serial_star("star", a, b)
    assert_table(
        bt.repeat(star, 3, name="root"),
        {"a": "SSS", "b": "RSSS"},
        """
        tick 1 2 3 4
        root R R R S
        star R S S S
        a    S . S S
        b    R S S S
        """,
    )


def test_repeat_fails_when_the_child_fails_and_then_counts_from_zero():
    assert_table(
        bt.repeat(a, 2, name="root"),
        {"a": "SFSS"},
        """
        tick 1 2 3 4
        root R F R S
        a    S F S S
        """,
    )


def test_retry_reruns_its_child_after_each_failure():
    assert_table(
        bt.retry(a, 3, name="root"),
        {"a": "FRFS"},
        """
        tick 1 2 3 4
        root R R R S
        a    F R F S
        """,
    )


def test_retry_gives_up_after_n_failures():
    assert_table(
        bt.retry(a, 2, name="root"),
        {"a": "FF"},
        """
        tick 1 2
        root R F
        a    F F
        """,
    )


def test_timeout_fires_on_the_nth_running_tick_and_halts_its_child():
    # Tick 3 is the third consecutive RUNNING tick: the root fails and star is halted, so at
    # tick 4 star starts over at a.
    star = bt.serial_star("star", a, b)
    assert_table(
        bt.timeout(star, 3, name="root"),
        {"a": "SS", "b": "RRRS"},
        """
        tick 1 2 3 4
        root R R F S
        star R R R S
        a    S . . S
        b    R R R S
        """,
    )


def test_timeout_counts_consecutive_ticks_of_one_run():
    # The first run finishes at once; the count starts again with the second run.
    assert_table(
        bt.timeout(a, 2, name="root"),
        {"a": "SRR"},
        """
        tick 1 2 3
        root S R F
        a    S R R
        """,
    )


def test_condition_must_not_return_running():
    with pytest.raises(ValueError, match="condition 'ready'"):
        run_script(bt.sequence("root", bt.condition("ready")), [[Status.RUNNING]])


def test_run_script_accepts_leaf_order_lists_and_node_id_dicts():
    tree = bt.sequence("root", a, b)
    by_list = run_script(tree, [[Status.SUCCESS, Status.RUNNING]])
    by_id = run_script(tree, [{1: Status.SUCCESS, 2: Status.RUNNING}])
    assert by_list[0] == by_id[0]
    assert by_list[0].status == Status.RUNNING and by_list[0].active_leaves == (1, 2)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: bt.Node(bt.Kind.SEQUENCE, "empty"), "needs at least one child"),
        (lambda: bt.Node(bt.Kind.INVERTER, "two", (a, b)), "exactly one child"),
        (lambda: bt.Node(bt.Kind.ACTION, "leaf", (a,)), "cannot have children"),
        (lambda: bt.repeat(a, 0), "count >= 1"),
    ],
)
def test_malformed_nodes_are_rejected(make, message):
    with pytest.raises(ValueError, match=message):
        make()
