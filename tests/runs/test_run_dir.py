"""Run directory I/O: exact CSV round trips, torn writes, batch bookkeeping, configuration."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mjxskill.errors import RunError
from mjxskill.runs.run_dir import (
    EVALUATIONS,
    Evaluations,
    Run,
    RunConfig,
    batch_sizes,
    evaluation_columns,
    read_csv,
)
from toy_runs import make_config, make_run, rows


def assert_same(a: Evaluations, b: Evaluations):
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)


def test_columns_follow_the_issue():
    assert evaluation_columns(("Push.a", "Push.b"), ("success", "applied_force")) == [
        "iteration", "Push.a", "Push.b", "objective_success", "objective_applied_force", "success_rate",
        "peak_contact_force", "mean_contact_force", "peak_commanded_force"]


def test_batch_sizes_match_the_optimizer_warmup_cut():
    # mjxskill.gp.ask cuts warm-up batches so that exactly n_init random points are drawn.
    from mjxskill import gp

    cfg = gp.MOBOConfig(bounds=((0, 0), (1, 1)), n_objectives=1, batch_size=4, n_init=6, seed=0)
    state, sizes = gp.init(cfg), []
    while len(state.x) < cfg.n_init:
        x = gp.ask(state)
        sizes.append(len(x))
        state = gp.tell(state, x, np.zeros((len(x), 1)))
    assert list(batch_sizes(10, 4, 6))[: len(sizes)] == sizes == [4, 2]
    assert list(batch_sizes(10, 4, 6)) == [4, 2, 4]


@given(budget=st.integers(1, 60), batch=st.integers(1, 9), n_init=st.integers(2, 60))
def test_batch_sizes_cover_the_budget_and_stop_at_the_warmup(budget, batch, n_init):
    sizes = list(batch_sizes(budget, batch, n_init))
    assert sum(sizes) == budget and all(1 <= q <= batch for q in sizes)
    ends = np.cumsum(sizes)
    if n_init <= budget:
        assert n_init in ends


finite = st.floats(allow_nan=False, width=64)


@settings(max_examples=50, deadline=None)
@given(values=st.lists(st.tuples(finite, finite, st.floats(width=64), finite, finite, st.floats(width=64), finite, finite),
                       min_size=1, max_size=5))
def test_csv_round_trips_float64_exactly(tmp_path_factory, values):
    path = tmp_path_factory.mktemp("csv") / "e.csv"
    v = np.array(values, np.float64)
    ev = Evaluations(np.arange(len(v)), v[:, :2], v[:, 2:4], v[:, 4], v[:, 5], v[:, 6], v[:, 7])
    cols = evaluation_columns(("a", "b"), ("o1", "o2"))
    from mjxskill.runs.run_dir import write_csv

    write_csv(path, cols, ev)
    back = read_csv(path, cols)
    np.testing.assert_array_equal(back.iteration, ev.iteration)
    assert not back.pooled  # the paper protocol's columns: no pooling fields
    for x, y in zip(back[1:7], ev[1:7]):
        assert x.tobytes() == y.tobytes() or np.array_equal(x, y, equal_nan=True)


@settings(max_examples=30, deadline=None)
@given(values=st.lists(st.tuples(finite, finite, st.floats(width=64), st.integers(1, 10**6), st.integers(-1, 10**6),
                                 st.floats(width=64)), min_size=1, max_size=5))
def test_pooled_csv_round_trips_exactly(tmp_path_factory, values):
    path = tmp_path_factory.mktemp("csv") / "e.csv"
    v = np.array(values, np.float64)
    n = len(v)
    ev = Evaluations(np.arange(n), v[:, :2], v[:, 2:3], v[:, 0], v[:, 1], v[:, 2], v[:, 5], worlds=v[:, 3].astype(int),
                     replaces=v[:, 4].astype(int), spread=v[:, 5:6])
    cols = evaluation_columns(("a", "b"), ("o1",), pooled=True)
    from mjxskill.runs.run_dir import write_csv

    write_csv(path, cols, ev)
    back = read_csv(path, cols)
    assert back.pooled
    for x, y in zip(back, ev):
        assert x.tobytes() == y.tobytes() or np.array_equal(x, y, equal_nan=True)


def test_append_then_read_and_a_torn_last_line_is_ignored(tmp_path):
    run = make_run(tmp_path)
    cfg = run.config()
    first, second = rows([0, 0, 0, 0]), rows([1, 1], seed=1)
    run.append(first)
    run.append(second)
    assert_same(run.evaluations(cfg), first.concat(second))
    # A kill in the middle of a write leaves part of a line: it is not a row.
    with open(run.path / EVALUATIONS, "a") as fh:
        fh.write("2,0.5,0.2,1.0")
    assert_same(read_csv(run.path / EVALUATIONS, cfg.columns()), first.concat(second))


def test_incomplete_batches_are_not_counted_and_reading_changes_nothing(tmp_path):
    run = make_run(tmp_path)
    cfg = run.config()  # batches of 4, 2, 4
    done = rows([0, 0, 0, 0, 1, 1])
    run.append(done)
    run.append(rows([2, 2], seed=3))  # 2 of the 4 rows of batch 2
    before = (run.path / EVALUATIONS).read_bytes()
    assert_same(run.evaluations(cfg), done)
    batches = run.batches(cfg)
    assert sorted(batches.complete) == [0, 1] and [r.line for r in batches.rejected] == [8, 9]
    assert all("batch 2 is incomplete (2 of 4 rows)" in r.reason for r in batches.rejected)
    assert (run.path / EVALUATIONS).read_bytes() == before


def test_config_round_trips_and_identifies_the_run(tmp_path):
    cfg = make_config(repeats=3, seed=5, optimizer_options={"n_raw": 64})
    run = make_run(tmp_path, cfg)
    assert run.config() == cfg
    assert (run.path / "scenario.yaml").read_text() == "name: toy\n"
    assert (run.path / "plan.txt").read_text() == "(a)\n"
    assert [r.path.name for r in run.sub_runs(cfg)] == ["seed-5", "seed-6", "seed-7"]
    assert cfg.sub_run(6).seed == 6 and cfg.sub_run(6).repeats == 1


def test_refuses_to_overwrite_a_run(tmp_path):
    make_run(tmp_path)
    with pytest.raises(RunError, match="already holds a run; continue it with --resume"):
        make_run(tmp_path)


@pytest.mark.parametrize(
    "text, message",
    [("format: other\n", "not an mjxskill run configuration"), ("[unclosed\n", "not valid YAML"),
     ("format: mjxskill.run/1\ntask: x\n", "missing key 'scenario'")],
)
def test_bad_config_files_name_the_file(tmp_path, text, message):
    (tmp_path / "config.yaml").write_text(text)
    with pytest.raises(RunError, match=message) as err:
        Run(tmp_path).config()
    assert "config.yaml" in str(err.value)


def test_not_a_run_directory(tmp_path):
    with pytest.raises(RunError, match="is not a run directory"):
        Run(tmp_path).config()


def test_csv_with_other_columns_is_refused(tmp_path):
    path = tmp_path / "e.csv"
    path.write_text("iteration,x\n0,1\n")
    with pytest.raises(RunError, match="does not have the columns"):
        read_csv(path, evaluation_columns(("a",), ("o",)))


def test_nan_objectives_survive(tmp_path):
    run = make_run(tmp_path)
    ev = rows([0, 0, 0, 0])
    ev.objectives[1, 0] = math.nan
    run.append(ev)
    back = run.evaluations()
    assert math.isnan(back.objectives[1, 0]) and back.objectives[0, 0] == ev.objectives[0, 0]


def test_config_bounds_that_leave_nothing_to_learn_are_named_not_blamed_on_options(tmp_path):
    text = make_config().to_yaml().replace("bounds:\n- - 0.0\n  - -1.0\n- - 1.0", "bounds:\n- - 0.0\n  - -1.0\n- - 0.0")
    assert "- - 0.0\n  - 1.0" in text  # the upper bounds are now (0.0, 1.0): S.x has [0, 0]
    (tmp_path / "config.yaml").write_text(text)
    with pytest.raises(RunError) as err:
        Run(tmp_path).config()
    line = text[: text.index("bounds:")].count("\n") + 1
    assert str(err.value) == (f"{tmp_path / 'config.yaml'}: bounds (line {line}): S.x: lower bound 0 is not below "
                              f"the upper bound 0")


def test_a_run_resumes_with_the_optimizer_defaults_it_began_with(tmp_path):
    # A config.yaml without optimizer_defaults (written by generation 1's code): its options were
    # relative to generation 1 (Chebyshev, hybrid), which it keeps; a new run records today's.
    from mjxskill.gp.settings import GENERATION, acquisition_defaults
    from mjxskill.runs.run_config import optimizer_config

    config = make_config()
    assert config.optimizer_defaults == GENERATION
    assert optimizer_config(config).acquisition == acquisition_defaults()
    old_text = config.to_yaml().replace(f"optimizer_defaults: {GENERATION}\n", "")
    old = RunConfig.from_yaml(old_text, "old/config.yaml")
    assert old.optimizer_defaults == 1 and optimizer_config(old).acquisition == acquisition_defaults(1)
    assert RunConfig.from_yaml(old.to_yaml(), "old/config.yaml") == old  # written back, it stays generation 1
    with pytest.raises(RunError, match=r"optimizer_defaults \(line \d+\).*got 'two'"):
        RunConfig.from_yaml(config.to_yaml().replace(f"optimizer_defaults: {GENERATION}", "optimizer_defaults: two"),
                            "bad/config.yaml")
