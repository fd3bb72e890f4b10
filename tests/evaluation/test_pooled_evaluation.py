"""A run's evaluation on disk (written chunk by chunk, resumed, reused when current), the pick of
one solution per run, and the pooled groups and tests of repeated runs; a scripted rollout in
place of the physics, every number computed again by brute force."""

import json

import numpy as np
import pytest
from scipy.stats import mannwhitneyu

from mjxskill.errors import RunError
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task
from mjxskill.evaluation.evaluate_run import CHUNKS, FOLDER, RESULT, evaluate_run, evaluation_current, evaluation_settings, load_evaluation
from mjxskill.evaluation.baselines import Candidates, Evaluation, mean_success_seconds
from mjxskill.evaluation.pooled import (Pick, contenders, force_bound, full_episode_seconds, group_force_and_time,
                                        paired_seconds, pick, pooled_samples, pooled_tests)
from mjxskill.scenario.schema import PickBound
from mjxskill.runs.run_dir import Evaluations
from mjxskill.evaluation.validation import Validation
from scripted import ScriptedRollout, expected
from push_runs import front_rows, push_run
from toy_evaluations import front_of, toy_evaluation

SCN = load_scenario("push")
TASK = plan_task(SCN)
N_KNOWN, N_UNSEEN = len(SCN.robot.start_configs), len(SCN.robot.eval_configs)


def settings(**changes):
    values = dict(per_config=3, n_random=4, seed=0, batch_size=3, engine="native", episode_seconds=0.2)
    values.update(changes)
    return evaluation_settings(**values)


@pytest.fixture()
def run(tmp_path):
    run = push_run(tmp_path / "run")
    front_rows(run, 3)
    return run


def test_an_evaluation_measures_success_force_and_time_per_configuration(run):
    rollout = ScriptedRollout(SCN, TASK.bounds)
    ev, tests, reused = evaluate_run(run, run.config(), rollout, TASK, settings())
    assert not reused and set(tests) >= {("known", "planner"), ("unseen", "random")}
    n = 3 + 1 + 4 + len(TASK.manual_parameters)
    assert ev.candidates.groups.count("pareto") == 3 and len(ev.candidates.names) == n
    assert [len(c) for c in rollout.calls] == [3, 3, 3, 3]  # chunks of 3, the last one padded
    success, force, seconds = expected(rollout, ev.candidates.params, N_KNOWN + N_UNSEEN, 3, SCN.bt_hz)
    np.testing.assert_allclose(ev.success, success)
    np.testing.assert_allclose(ev.peak_commanded_force, force)
    np.testing.assert_allclose(ev.success_seconds, seconds)  # NaN where no world succeeded
    assert ev.config_names[N_KNOWN] == "unseen-0" and ev.known.sum() == N_KNOWN
    # per world: the tick the tree returned SUCCESS, (tick + 1) / bt_hz s; NaN where it failed
    worlds = np.array([[[(t + 1) / SCN.bt_hz if ok else np.nan
                         for r in range(3) for ok, _, t in [rollout.outcome(p, c, r)]]
                        for c in range(N_KNOWN + N_UNSEEN)] for p in ev.candidates.params])
    np.testing.assert_array_equal(ev.world_seconds, worlds)
    assert load_evaluation(run)[0].world_seconds.shape == (n, N_KNOWN + N_UNSEEN, 3)
    # the mean time over several candidates weights each configuration by its successes
    rows = [0, 1, 2]
    times = [(t + 1) / SCN.bt_hz for i in rows for c in range(N_KNOWN + N_UNSEEN) for r in range(3)
             for ok, _, t in [rollout.outcome(ev.candidates.params[i], c, r)] if ok]
    assert mean_success_seconds(ev, rows) == pytest.approx(np.mean(times))


def test_the_evaluation_file_round_trips_and_a_current_one_is_reused(run):
    first = ScriptedRollout(SCN, TASK.bounds)
    ev, _, _ = evaluate_run(run, run.config(), first, TASK, settings())
    folder = run.path / FOLDER
    assert {p.name for p in folder.iterdir()} == {RESULT, "evaluation.csv", "success.png"}  # the chunks are gone
    json.loads((folder / RESULT).read_text())  # plain JSON: NaN written as null
    assert "NaN" not in (folder / RESULT).read_text()
    back, own = load_evaluation(run)
    assert own == settings()
    for a, b in zip(ev, back):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b)
        elif isinstance(a, Candidates):
            assert a.names == b.names and a.groups == b.groups and np.array_equal(a.params, b.params)
        else:
            assert a == b
    again = ScriptedRollout(SCN, TASK.bounds)
    _, _, reused = evaluate_run(run, run.config(), again, TASK, settings(batch_size=5))  # grouping only: same numbers
    assert reused and again.calls == []
    assert evaluation_current(run, run.config(), settings()) and not evaluation_current(run, run.config(), settings(seed=1))
    other = ScriptedRollout(SCN, TASK.bounds)
    _, _, reused = evaluate_run(run, run.config(), other, TASK, settings(per_config=2))
    assert not reused and other.calls


def test_a_killed_evaluation_continues_from_its_chunks(run, tmp_path):
    reference, _, _ = evaluate_run(push_copy(run, tmp_path), run.config(), ScriptedRollout(SCN, TASK.bounds), TASK, settings())
    with pytest.raises(KeyboardInterrupt):
        evaluate_run(run, run.config(), ScriptedRollout(SCN, TASK.bounds, stop_after=2), TASK, settings())
    chunks = run.path / FOLDER / CHUNKS
    lines = chunks.read_text().splitlines()
    assert len(lines) == 2 and not (run.path / FOLDER / RESULT).exists()
    chunks.write_text(lines[0] + "\n" + lines[1][: len(lines[1]) // 2])  # the second one cut short by a kill
    rest = ScriptedRollout(SCN, TASK.bounds)
    ev, _, _ = evaluate_run(run, run.config(), rest, TASK, settings())
    assert len(rest.calls) == 3  # chunk 0 kept; 1 (cut), 2 and 3 evaluated
    np.testing.assert_array_equal(ev.success, reference.success)
    np.testing.assert_array_equal(ev.success_seconds, reference.success_seconds)


def push_copy(run, tmp_path):
    import shutil

    shutil.copytree(run.path, tmp_path / "copy")
    from mjxskill.runs.run_dir import Run

    return Run(tmp_path / "copy")


def test_the_pick_is_the_most_successful_training_solution_within_the_stated_force():
    ev = toy_evaluation(np.ones((3, 3)), manual_force=[4.0, 6.0])
    # training: row 2 succeeds most but presses 9 N, beyond a 6 N bound
    front = front_of(ev, [0.5, 0.8, 1.0], [2.0, 5.0, 9.0], [1.0, 2.0, 3.0])
    assert pick(front, ev, max_force=6.0) == Pick(1, 6.0, "given (--max-force)")
    # the operators' sets (6 N at most here) no longer bound it: without a bound row 2 is picked
    unbounded = pick(front, ev)
    assert unbounded.row == 2 and unbounded.bound is None and unbounded.source.startswith("none")
    assert pick(front, ev, max_force=10).row == 2
    assert pick(front, ev, max_force=1).row is None  # nothing within 1 N: the run has no pick
    tied = front_of(ev, [0.8, 0.8, 0.8], [1.0, 1.0, 1.0], [1.0, 5.0, 3.0])
    assert pick(tied, ev).row == 1  # ties: the higher first objective
    with pytest.raises(Exception, match="evaluate the run again"):
        pick(front_of(ev, [0.5, 0.8], [1, 1], [1, 2]), ev)  # a front that is not the evaluated one


def test_the_bound_is_the_commands_else_the_scenarios_with_its_reason():
    stated = PickBound(10.0, "the skill's bound")
    assert force_bound(4.0, stated) == (4.0, "given (--max-force)")
    assert force_bound(None, stated) == (10.0, "the scenario's pick.max_force: the skill's bound")
    assert force_bound(None, None)[0] is None
    assert force_bound(None, SCN.pick)[0] == 10.0  # push.yaml's


def test_a_validated_pick_takes_the_contender_most_successful_in_the_validation_worlds():
    ev = toy_evaluation(np.ones((5, 3)), manual_force=[4.0, 6.0])
    # rows 0 and 1 tie at 100 % training success; row 0 has the higher first objective (the
    # training pick) but is a knife-edge set (20 % in validation), row 1 is robust (90 %); row 3
    # presses beyond a 6 N bound, row 4 trails in training and is not validated
    front = front_of(ev, [1.0, 1.0, 0.8, 1.0, 0.5], [2.0, 3.0, 1.0, 9.0, 1.0], [5.0, 4.0, 3.0, 9.0, 1.0])
    assert pick(front, ev, 6.0).row == 0
    assert contenders(front, 6.0, 3) == [0, 1, 2] and contenders(front, None, 2) == [3, 0]
    assert contenders(front, 0.5, 3) == []
    validated = pick(front, ev, 6.0, Validation((0, 1, 2), np.array([0.2, 0.9, 0.9]), 20), "stated")
    assert validated == Pick(1, 6.0, "stated")  # 0.9 tie: the training success
    assert pick(front, ev, 6.0, Validation((0, 1, 2), np.array([0.2, 0.5, 0.9]), 20)).row == 2
    assert pick(front, ev, max_force=0.5, validation=Validation((), np.zeros(0), 20)).row is None
    with pytest.raises(Exception, match="validate the run again"):
        pick(front, ev, 6.0, Validation((0, 2), np.array([0.2, 0.9]), 20))  # not the two in contention


def test_of_validated_contenders_equally_successful_the_faster_is_picked():
    ev = toy_evaluation(np.ones((3, 3)), manual_force=[4.0])
    # training: row 0 best (100 %, highest first objective); in validation rows 0 and 2 tie at
    # 90 %, row 2 reaching success in 6.5 s on average (failures as the whole episode), row 0 in 8 s
    front = front_of(ev, [1.0, 0.9, 0.8], [1.0, 1.0, 1.0], [3.0, 2.0, 1.0])
    timed = Validation((0, 1, 2), np.array([0.9, 0.5, 0.9]), 20, 3, np.array([8.0, 2.0, 6.5]))
    assert pick(front, ev, 6.0, timed).row == 2
    # the fastest of all (row 1) succeeds less: success decides first
    assert pick(front, ev, 6.0, timed._replace(seconds=np.array([8.0, 2.0, 8.0]))).row == 0  # equal times: training
    assert pick(front, ev, 6.0, timed._replace(seconds=None)).row == 0  # no times: the training success decides


def test_the_validation_rolls_out_the_contenders_in_fresh_known_worlds_and_is_reused(run):
    from mjxskill.evaluation.validation import FILE, load_validation, validate, validation_settings

    def vsettings(**changes):
        values = dict(per_config=2, candidates=2, seed=3, engine="native", episode_seconds=0.2)
        values.update(changes)
        return validation_settings(**values)

    front = run.front(run.config())
    rollout = ScriptedRollout(SCN, TASK.bounds)
    v, reused = validate(run, front, [2, 0], rollout, vsettings())
    assert not reused and v.rows == (2, 0) and v.worlds == 2 * N_KNOWN
    # only the known start configurations: the unseen ones stay for the evaluation
    success = expected(rollout, front.params[[2, 0]], N_KNOWN, 2, SCN.bt_hz)[0].mean(axis=1)
    np.testing.assert_allclose(v.success, success)
    # the mean time to success over the same worlds, a failure counted as the 0.2 s episode
    seconds = [np.mean([(t + 1) / SCN.bt_hz if ok else 0.2 for c in range(N_KNOWN) for r in range(2)
                        for ok, _, t in [rollout.outcome(p, c, r)]]) for p in front.params[[2, 0]]]
    np.testing.assert_allclose(v.seconds, seconds)
    assert [len(c) for c in rollout.calls] == [2]  # one call of the two rows, not padded to a batch
    doc = json.loads((run.path / FOLDER / FILE).read_text())
    assert doc["rows"] == [2, 0] and doc["worlds"] == 2 * N_KNOWN
    again = ScriptedRollout(SCN, TASK.bounds)
    v2, reused = validate(run, front, [0], again, vsettings(candidates=1))  # a subset: reused
    assert reused and again.calls == [] and v2.rows == (0,) and v2.success[0] == pytest.approx(success[1])
    assert v2.seconds_of(0) == pytest.approx(seconds[1])
    assert load_validation(run, front, [1], vsettings()) is None  # row 1 was not validated
    assert load_validation(run, front, [0], vsettings(seed=4)) is None  # other worlds
    moved = Evaluations(front.iteration, front.params + 0.01, *front[2:])  # not _replace: len() is rows
    assert load_validation(run, moved, [0], vsettings()) is None  # another front
    # nothing within the bound: nothing rolled out, nothing written, the same answer when read
    empty, reused = validate(run, front, [], again, vsettings())
    assert empty.rows == () and again.calls == [] and load_validation(run, front, [], vsettings()).rows == ()
    good = (run.path / FOLDER / FILE).read_text()
    # one written before times were kept is made again, not used without them
    old = json.loads(good)
    del old["seconds"]
    (run.path / FOLDER / FILE).write_text(json.dumps(old))
    assert load_validation(run, front, [0], vsettings()) is None
    (run.path / FOLDER / FILE).write_text(good)
    for damaged in ('{"format": "mjxskill.validation/1", "rows": [0], "success": [1.5]}',
                    good.replace('"worlds": 8', '"worlds": 1e400'), good.replace('"worlds": 8', '"worlds": 8.5'),
                    good.replace('"rows": [\n  2,', '"rows": [\n  true,'), good.replace('"rows": [\n  2,\n  0\n ]', '"rows": []'),
                    good[:-20], "[" * 100000 + "]" * 100000, good.replace('"seconds": [', '"seconds": [-1, ')):
        assert damaged != good
        (run.path / FOLDER / FILE).write_text(damaged)
        with pytest.raises(RunError, match=f"{FILE} is not a readable validation"):
            load_validation(run, front, [0], vsettings())


def timed_evaluation(picked, operators) -> Evaluation:
    """A Pareto row per ``picked`` (C, W) and a manual row per ``operators`` (C, W): times to success, NaN: failed."""
    groups = ("pareto",) * len(picked) + ("manual",) * len(operators)
    names = tuple(f"pareto-{i}" for i in range(len(picked))) + tuple(f"op{i}" for i in range(len(operators)))
    seconds = np.array([*picked, *operators], float)
    return Evaluation(Candidates(names, groups, np.zeros((len(groups), 1))), np.isfinite(seconds).mean(axis=2),
                      np.array([True, False]), ("known-0", "unseen-0"), world_seconds=seconds)


def test_time_to_success_is_compared_on_paired_worlds_and_with_failures_as_full_episodes():
    nan = np.nan
    # two configurations x two worlds; run 1 picks pareto-0, run 2 pareto-1 (which never succeeds)
    one = timed_evaluation([[[2, nan], [4, 6]]], [[[3, 5], [nan, 8]], [[nan, nan], [5, nan]]])
    two = timed_evaluation([[[9, 9], [9, 9]], [[nan, nan], [nan, nan]]], [[[1, 1], [1, 1]], [[nan, nan], [nan, nan]]])
    evals, picks = [one, two], [Pick(0, None, "x"), Pick(1, None, "x")]
    # paired, by hand: worlds where the pick and an operator set both succeeded: run 1 pairs
    # (2, 3) and (6, 8) with op0, (4, 5) with op1; run 2's pick succeeds nowhere
    assert paired_seconds(evals, picks, "picked", "manual") == pytest.approx((12 / 3, 16 / 3, 3))
    # failures as the 10 s episode: the pick 2, 10, 4, 6 and four times 10 -> 62 / 8; the operators
    # 3, 5, 10, 8 | 10, 10, 5, 10 | 1, 1, 1, 1 | 10, 10, 10, 10 -> 105 / 16
    assert full_episode_seconds(evals, picks, "picked", 10.0) == pytest.approx(62 / 8)
    assert full_episode_seconds(evals, picks, "manual", 10.0) == pytest.approx(105 / 16)
    # the pick is faster where both succeed and slower once its failures count: the rows can disagree
    assert 12 / 3 < 16 / 3 and 62 / 8 > 105 / 16
    # an evaluation without per-world times gives no number rather than a wrong one
    old = one._replace(world_seconds=None)
    assert paired_seconds([old], picks[:1], "picked", "manual")[2] == 0
    assert np.isnan(full_episode_seconds([old], picks[:1], "picked", 10.0))


def test_pooled_samples_are_one_per_run_candidate_and_configuration():
    a = toy_evaluation(np.array([[1.0, 0.5, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]), [4.0, 6.0])
    b = toy_evaluation(np.array([[0.5, 0.5, 1.0], [1.0, 0.0, 0.5], [0.0, 0.0, 0.0]]), [4.0, 6.0])
    picks = [Pick(0, 6.0, "x"), Pick(1, 6.0, "x")]
    samples = pooled_samples([a, b], picks)
    np.testing.assert_array_equal(samples["picked"][0], [1.0, 0.5, 1.0, 0.0])  # run a row 0, run b row 1; known
    np.testing.assert_array_equal(samples["picked"][1], [0.0, 0.5])
    assert len(samples["pareto"][0]) == 2 * 3 * 2 and len(samples["random"][1]) == 2 * 2 * 1
    tests = pooled_tests(samples)
    assert set(tests) == {"pareto", "planner", "random", "manual"}
    for baseline in ("planner", "random", "manual"):
        for side in (0, 1):
            direct = mannwhitneyu(samples["picked"][side], samples[baseline][side], alternative="two-sided").pvalue
            assert tests[baseline][("known", "unseen")[side]] == pytest.approx(direct)
    force, _ = group_force_and_time([a, b], picks, "manual")
    assert force == pytest.approx(5.0)
    # a run without a pick adds no picked sample
    assert len(pooled_samples([a, b], [picks[0], Pick(None, 6.0, "x")])["picked"][0]) == 2
