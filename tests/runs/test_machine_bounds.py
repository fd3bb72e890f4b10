"""Sizes are bounded by the machine, not only by numbers: worker processes and
the episodes of one call against the available memory (measured per worker and per episode,
``mjxskill.runs.bounds``), one per-call bound for every command; and only regular files are read
where a user hands a file: a FIFO or a device is one located error, never opened for reading."""

import os
import signal

import pytest
from hypothesis import given, settings, strategies as st

from cli_helpers import error_line, invoke, snapshot
from mjxskill.runs import bounds
from mjxskill.runs.bounds import (EPISODE_BYTES, MAX_CALL_EPISODES, MAX_WORKERS, WORKER_BYTES, call_episodes_problem,
                                  workers_problem)
from push_runs import front_rows, push_run

GIB = 2**30


@pytest.fixture
def watchdog():
    """Fails a test that blocks (a FIFO opened for reading waits for a writer forever)."""
    def fail(*_):
        raise TimeoutError("blocked: a FIFO was opened for reading")
    old = signal.signal(signal.SIGALRM, fail)
    signal.alarm(120)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


@settings(max_examples=200, deadline=None)
@given(workers=st.integers(1, 10**6), available=st.integers(0, 2**40))
def test_workers_fit_the_available_memory_or_are_refused_with_the_numbers(workers, available):
    problem = workers_problem(workers, available)
    fits = workers <= MAX_WORKERS and workers * WORKER_BYTES <= available
    assert (problem is None) == fits
    if problem is not None and workers <= MAX_WORKERS:
        assert f"{workers} workers" in problem and "MiB each, measured" in problem and "available" in problem


@settings(max_examples=200, deadline=None)
@given(episodes=st.integers(1, 10**9), available=st.integers(0, 2**40))
def test_a_call_fits_the_bound_and_the_memory_or_is_refused(episodes, available):
    problem = call_episodes_problem(episodes, "batches", available)
    assert (problem is None) == (episodes <= MAX_CALL_EPISODES and episodes * EPISODE_BYTES <= available)
    if problem is not None:
        assert f"make {episodes} episodes per call" in problem


def test_the_measured_numbers_are_plausible():
    assert 100 * 2**20 <= WORKER_BYTES <= 2 * GIB and 1024 <= EPISODE_BYTES <= 2**20
    assert bounds.available_memory() is None or bounds.available_memory() > 0


@pytest.mark.parametrize("command", ["evaluate", "train", "experiment"])
def test_more_workers_than_the_memory_holds_are_refused(tmp_path, capsys, monkeypatch, command):
    run = push_run(tmp_path / "run")
    before = snapshot(run.path)
    monkeypatch.setattr(bounds, "available_memory", lambda: GIB)  # 1 GiB holds 2 workers
    args = [run.path] if command == "evaluate" else ["push", "--out", tmp_path / "out"]
    code, err = invoke(capsys, command, *args, "--workers", "3")
    assert code == 2 and "--workers" in err and "3 workers need about 1.1 GiB" in err and "at most 2 fit" in err, err
    assert "Traceback" not in err and snapshot(run.path) == before and not (tmp_path / "out").exists()


def test_256_workers_are_refused_here_unless_the_machine_holds_them(tmp_path, capsys):
    available = bounds.available_memory()
    if available is not None and available >= 256 * WORKER_BYTES:
        pytest.skip("this machine holds 256 workers")
    code, err = invoke(capsys, "train", "push", "--workers", "256", "--out", tmp_path / "out")
    assert code == 2 and "256 workers need" in err and "Traceback" not in err, err
    assert not (tmp_path / "out").exists()


def test_an_evaluation_of_millions_of_episodes_per_call_is_refused_as_train_refuses_them(tmp_path, capsys):
    run = push_run(tmp_path / "run")
    front_rows(run, 2)
    before = snapshot(run.path)
    code, err = invoke(capsys, "evaluate", run.path, "--per-config", "1000", "--batch-size", "4096", "--random", "10000")
    error_line(code, err, "evaluate", "--batch-size 4096 x --per-config 1000", f"more than {MAX_CALL_EPISODES}")
    assert snapshot(run.path) == before


def test_an_evaluation_call_the_memory_cannot_hold_is_refused(tmp_path, capsys, monkeypatch):
    run = push_run(tmp_path / "run")
    front_rows(run, 2)
    before = snapshot(run.path)
    monkeypatch.setattr(bounds, "available_memory", lambda: 2**20)
    code, err = invoke(capsys, "evaluate", run.path, "--per-config", "20", "--batch-size", "8")
    error_line(code, err, "evaluate", "episodes per call, which need about", "KiB each, measured")
    assert snapshot(run.path) == before


def test_a_training_call_the_memory_cannot_hold_is_refused_before_a_directory(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(bounds, "available_memory", lambda: 2**20)
    code, err = invoke(capsys, "train", "push", "--batch-size", "64", "--worlds", "64", "--out", tmp_path / "out")
    error_line(code, err, "train", "--worlds", "4096 episodes per call, which need about")
    assert list(tmp_path.iterdir()) == []


# -- only regular files are read ------------------------------------------------------------------
@pytest.mark.parametrize("command", ["plan", "train"])
def test_a_fifo_or_a_device_as_the_scenario_is_refused_unopened(tmp_path, capsys, watchdog, command):
    fifo = tmp_path / "scenario.yaml"
    os.mkfifo(fifo)
    for path, kind in ((fifo, "a FIFO"), ("/dev/zero", "a character device")):
        extra = ["--out", tmp_path / "out"] if command == "train" else []
        code, err = invoke(capsys, command, path, *extra)
        error_line(code, err, command, str(path), kind, "not a regular file")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scenario.yaml"]


@pytest.mark.parametrize("command, flags, name", [("train", ["--resume"], "evaluations.csv"), ("evaluate", [], "pareto.csv"),
                                                 ("select", [], "pareto.csv")])
def test_a_fifo_in_a_runs_place_of_its_files_is_refused_unopened(tmp_path, capsys, watchdog, command, flags, name):
    run = push_run(tmp_path / "run")
    front_rows(run, 2)
    csv = run.path / name
    csv.unlink()
    os.mkfifo(csv)
    args = ["push", *flags, run.path] if command == "train" else [run.path]
    code, err = invoke(capsys, command, *args)
    if name == "evaluations.csv":
        error_line(code, err, command, str(csv), "a FIFO")
    else:  # never opened: a pareto.csv that is not a regular file is no Pareto front
        error_line(code, err, command, "pareto.csv")


# each command and the run files it reads (train --resume: those it replaces after a batch too)
READS = {"train": ["config.yaml", "scenario.yaml", "evaluations.csv", "run_state.json", "pareto.csv", "optimizer_state.npz"],
         "select": ["config.yaml", "pareto.csv"],
         "evaluate": ["config.yaml", "pareto.csv", "scenario.yaml"]}


@pytest.mark.parametrize("command, name", [(c, n) for c, names in READS.items() for n in names])
def test_a_fifo_in_place_of_any_run_file_is_refused_by_name_unopened(tmp_path, capsys, watchdog, command, name):
    """Every reader of a run's files asks what is there first (``mjxskill._files.is_regular``,
    ``read_regular``): a FIFO is one error naming it, "is not a regular file", never waited on
    and never taken for a missing file; nothing of the run changes."""
    run = push_run(tmp_path / "run")
    front_rows(run, 2)
    path = run.path / name
    if path.exists():
        path.unlink()
    os.mkfifo(path)
    before = snapshot(run.path)
    args = ["push", "--resume", run.path, "--workers", 1] if command == "train" else [run.path]
    code, err = invoke(capsys, command, *args, *(["--no-render"] if command == "select" else []))
    error_line(code, err, command, str(path), "is not a regular file but a FIFO")
    assert snapshot(run.path) == before
    from mjxskill.gp import load_state

    if name == "optimizer_state.npz":  # the library's reader of the optimizer state too
        with pytest.raises(OSError, match="is not a regular file but a FIFO"):
            load_state(path)
