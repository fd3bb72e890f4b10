"""An experiment's training time is in its state batch by batch: a process killed mid-run (no
``finally`` runs under SIGKILL) keeps the seconds and rows of every batch already on disk."""

import json

import numpy as np

from mjxskill.experiment.directory import Experiment
from mjxskill.experiment.driver import TrainClock


class Reporter:
    def __init__(self):
        self.calls = []

    def start(self, ev, reference):
        self.calls.append("start")

    def update(self, new, ev, reference):
        self.calls.append("update")

    def close(self):
        self.calls.append("close")


def _times(path):
    return json.loads((path / "state.json").read_text())["times"]["optimizer/seed-3"]


def test_each_batch_on_disk_is_in_the_state_before_the_next_is_evaluated(tmp_path):
    exp, inner = Experiment(tmp_path), Reporter()
    clock = TrainClock(exp, "optimizer/seed-3", inner)
    evaluate = clock.evaluator(lambda params, iteration: params.sum(axis=1))
    clock.start(None, None)
    assert not (tmp_path / "state.json").exists()
    for batch in range(3):
        np.testing.assert_array_equal(evaluate(np.ones((2, 3)), batch), [3.0, 3.0])
        clock.update(None, None, None)  # the loop reports a batch once it is written
        times = _times(tmp_path)
        assert times["train_seconds_evaluations"] == times["simulation_seconds_evaluations"] == 2 * (batch + 1)
        assert times["train_seconds"] >= times["simulation_seconds"] >= 0.0
    evaluate(np.ones((2, 3)), 3)  # the batch in flight when the process is killed: never recorded
    assert _times(tmp_path)["train_seconds_evaluations"] == 6
    clock.close()
    assert inner.calls == ["start", "update", "update", "update", "close"] and clock.recorded


def test_a_run_with_nothing_left_to_evaluate_adds_no_time(tmp_path):
    exp = Experiment(tmp_path)
    clock = TrainClock(exp, "optimizer/seed-3")
    clock.start(None, None)
    clock.update(None, None, None)  # a replayed batch: no evaluation
    clock.record()
    assert not (tmp_path / "state.json").exists() and not clock.recorded
