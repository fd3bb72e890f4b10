"""The training loop with a closed-form objective in place of the physics: batch bookkeeping,
flush-before-propose, interrupt/resume equivalence, Pareto file, hypervolume reference."""

import numpy as np
import pytest

from mjxskill.errors import Notice
from mjxskill.gp import hypervolume
from mjxskill.runs.run_dir import EVALUATIONS, OPTIMIZER_STATE, PARETO, read_csv
from mjxskill.cli.progress import Progress
from mjxskill.training.front import hypervolume_history, hypervolume_reference
from mjxskill.training.loop import train
from toy_runs import CONFIG, Recorder, new_run, toy_objective


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("loop")
    run = new_run(tmp, "full")
    recorder = Recorder(run)
    ev = train(run, CONFIG, recorder, progress=Progress(CONFIG.budget, quiet=True))
    return run, ev, recorder


def test_runs_to_the_budget_in_the_expected_batches(uninterrupted):
    run, ev, recorder = uninterrupted
    assert [it for it, _ in recorder.calls] == [0, 1, 2]
    assert [len(x) for _, x in recorder.calls] == [4, 2, 4]
    assert len(ev) == 10 and list(ev.iteration) == [0] * 4 + [1] * 2 + [2] * 4
    lo, hi = np.asarray(CONFIG.bounds)
    assert np.all((ev.params >= lo) & (ev.params <= hi))
    np.testing.assert_array_equal(ev.objectives, np.concatenate([toy_objective(x, i).objectives for i, x in recorder.calls]))
    assert (run.path / OPTIMIZER_STATE).is_file()


def test_pareto_csv_holds_exactly_the_non_dominated_rows(uninterrupted):
    run, ev, _ = uninterrupted
    y = ev.objectives
    # Brute force, larger is better: dominated if another row is >= everywhere and > somewhere.
    dominated = [any(np.all(y[j] >= y[i]) and np.any(y[j] > y[i]) for j in range(len(y))) for i in range(len(y))]
    front = read_csv(run.path / PARETO, CONFIG.columns())
    expected = {tuple(r) for r in y[~np.array(dominated)]}
    assert {tuple(r) for r in front.objectives} == expected and len(front.objectives) == len(expected)


def test_each_batch_is_on_disk_before_the_next_proposal(uninterrupted):
    # When batch k is evaluated, batches 0..k-1 are already in the CSV on disk.
    _, _, recorder = uninterrupted
    assert recorder.rows_on_disk == [0, 4, 6]


def test_interrupted_then_resumed_equals_uninterrupted(tmp_path, uninterrupted):
    full_run, full_ev, _ = uninterrupted
    run = new_run(tmp_path, "cut")
    first = Recorder(stop_after=1)
    with pytest.raises(KeyboardInterrupt):
        train(run, CONFIG, first)
    second = Recorder()
    ev = train(run, CONFIG, second)
    # No batch evaluated twice, none lost, and the very same proposals and results.
    assert [it for it, _ in first.calls + second.calls] == [0, 1, 2]
    assert (run.path / EVALUATIONS).read_text() == (full_run.path / EVALUATIONS).read_text()
    assert (run.path / PARETO).read_text() == (full_run.path / PARETO).read_text()
    for a, b in zip(ev, full_ev):
        np.testing.assert_array_equal(a, b)


def test_a_torn_batch_is_evaluated_again_on_resume(tmp_path, uninterrupted):
    full_run, _, _ = uninterrupted
    run = new_run(tmp_path, "torn")
    with pytest.raises(KeyboardInterrupt):
        train(run, CONFIG, Recorder(stop_after=2))
    text = (full_run.path / EVALUATIONS).read_text().splitlines(keepends=True)
    with open(run.path / EVALUATIONS, "a") as fh:  # a kill while batch 2 was being written
        fh.write("".join(text[7:9]) + text[9][:12])
    second = Recorder()
    with pytest.warns(Notice, match="set aside"):  # the torn rows are kept beside the file, and said
        train(run, CONFIG, second)
    assert [it for it, _ in second.calls] == [2]
    assert (run.path / EVALUATIONS).read_text() == (full_run.path / EVALUATIONS).read_text()


def test_hypervolume_reference_is_worst_warmup_plus_a_tenth_of_its_range():
    warm = np.array([[1.0, -2.0], [3.0, -1.0], [2.0, -5.0]])  # larger is better
    # minimized space: z = -y; worst = max z = (-1, 5), best = (-3, 1), range (2, 4)
    np.testing.assert_allclose(hypervolume_reference(warm), [-1 + 0.2, 5 + 0.4])


def test_hypervolume_history_is_monotone_and_matches_a_direct_computation(uninterrupted):
    run, ev, _ = uninterrupted
    ref = np.asarray(run.run_state()["hv_reference"])
    np.testing.assert_array_equal(ref, hypervolume_reference(ev.objectives[: CONFIG.n_init]))
    done, hv = hypervolume_history(ev, ref)
    assert list(done) == [4, 6, 10]
    assert np.all(np.diff(hv) >= 0)
    assert hv[-1] == hypervolume(-ev.objectives, ref) > 0
