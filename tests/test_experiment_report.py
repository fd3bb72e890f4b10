"""An experiment directory and its report, with hand-made training rows and a scripted rollout in
place of the physics: which runs it holds, which repetitions are finished, the pick, the pooled
groups and tests, the normalized hypervolume and front sizes, report.json and report.md."""

import json

import numpy as np
import pytest
import yaml
from scipy.stats import mannwhitneyu

from mjxskill.errors import RunError
from mjxskill.gp import hypervolume
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task, planning_texts
from mjxskill.training.evaluate_run import evaluate_run
from mjxskill.training.experiment import Experiment, Protocol, write_report
from mjxskill.training.experiment.directory import repetition_settings
from mjxskill.training.experiment.stats import normalization, normalized_curve
from mjxskill.training.front import pareto_mask_of
from mjxskill.training.run_dir import Evaluations, RunConfig, batch_sizes
from mjxskill.training.runs import directory_kind, runs_in
from scripted import ScriptedRollout, expected

SCN = load_scenario("push")
TASK = plan_task(SCN)
N_KNOWN, N_UNSEEN = len(SCN.robot.start_configs), len(SCN.robot.eval_configs)
CONFIG = RunConfig(task="push", scenario="push", goal=TASK.goal, parameter_names=TASK.parameter_names,
                   parameter_units=TASK.parameter_units, bounds=tuple(tuple(map(float, b)) for b in TASK.bounds),
                   objective_names=SCN.objective_names, budget=8, batch_size=3, n_init=3, worlds=2, seed=5,
                   episode_seconds=0.2, repeats=2, engine="native")
PROTOCOL = Protocol(per_config=2, random_sets=3, max_force=None)


def training_rows(seed: int, kind: int) -> Evaluations:
    """A full budget of rows in the run's batches, reproducible from (seed, kind)."""
    rng = np.random.default_rng([seed, kind])
    sizes = list(batch_sizes(CONFIG.budget, CONFIG.batch_size, CONFIG.n_init))
    n = sum(sizes)
    lo, hi = np.asarray(CONFIG.bounds)
    return Evaluations(np.repeat(np.arange(len(sizes)), sizes), lo + rng.random((n, 4)) * (hi - lo),
                       rng.normal(size=(n, 2)) * [100, 10] + [500, 100], rng.integers(0, 3, n) / 2, rng.random(n) * 1.6)


def fill(run, ev):
    config = run.config()
    run.write_evaluations(config, ev)
    run.write_pareto(config, ev, pareto_mask_of(ev))


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    exp = Experiment(tmp_path_factory.mktemp("exp") / "exp")
    exp.create(CONFIG, PROTOCOL, SCN.source, planning_texts(TASK))
    rollout = ScriptedRollout(SCN, TASK.bounds)
    for i, (opt, rnd) in enumerate(exp.runs(CONFIG)):
        fill(opt, training_rows(CONFIG.seed + i, 0))
        if i == 1:  # the first repetition's random search is not finished
            fill(rnd, training_rows(CONFIG.seed + i, 1))
        evaluate_run(opt, opt.config(), rollout, TASK, repetition_settings(CONFIG, PROTOCOL, CONFIG.seed + i))
    write_report(exp)
    return exp, rollout


def test_the_directory_says_which_runs_it_holds_and_of_which_kind(experiment):
    exp, _ = experiment
    assert directory_kind(exp.path) == "experiment" and directory_kind(exp.optimizer.path) == "repeated"
    assert directory_kind(exp.optimizer.path / "seed-5") == "run"
    refs = runs_in(exp.path)
    assert [(r.kind, r.seed, r.path.relative_to(exp.path).as_posix()) for r in refs] == [
        ("optimizer", 5, "optimizer/seed-5"), ("optimizer", 6, "optimizer/seed-6"),
        ("random_search", 5, "random_search/seed-5"), ("random_search", 6, "random_search/seed-6")]
    assert runs_in(exp.path / "random_search" / "seed-6") == [refs[3]]
    assert yaml.safe_load((exp.path / "random_search" / "config.yaml").read_text())["optimizer"] == "random"
    assert exp.protocol() == PROTOCOL
    with pytest.raises(RunError, match="not a run directory"):
        runs_in(exp.path / "nothing")


def test_an_experiment_is_created_only_where_nothing_is(experiment, tmp_path):
    exp, _ = experiment
    with pytest.raises(RunError, match="already holds an experiment; continue it with --resume"):
        Experiment(exp.path).create(CONFIG, PROTOCOL, SCN.source, {})
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("mine")
    with pytest.raises(RunError, match="is not empty"):
        Experiment(tmp_path / "mine").create(CONFIG, PROTOCOL, SCN.source, {})
    assert (tmp_path / "mine" / "notes.txt").read_text() == "mine"


def test_the_report_covers_the_finished_repetitions_with_the_stated_pick(experiment):
    exp, rollout = experiment
    report = json.loads((exp.path / "report.json").read_text())
    assert report["task"] == "push" and report["status"] == {"repetitions_done": 1, "repetitions": 2}
    protocol = report["protocol"]
    for key, value in dict(budget=8, batch_size=3, n_init=3, worlds=2, seed=5, repeats=2, engine="native",
                           per_config=2, random_sets=3, max_force=None, known_configs=N_KNOWN, unseen_configs=N_UNSEEN).items():
        assert protocol[key] == value, key
    # the pick, by hand: the highest training success within the operators' largest commanded force
    opt = exp.optimizer.sub_runs(CONFIG)[1]
    front = opt.front(opt.config())
    assert report["picked"][0]["seed"] == 6
    params = np.array([[m.values[n] for n in TASK.parameter_names] for m in SCN.manual_parameters.values()])
    bound = expected(rollout, params, N_KNOWN + N_UNSEEN, 2, SCN.bt_hz)[1].max()
    ok = front.max_force <= bound
    assert not ok.all() and front.success_rate[~ok].max() == 1  # the bound excludes a fully successful solution
    best = max(np.flatnonzero(ok), key=lambda k: (front.success_rate[k], front.objectives[k, 0]))
    assert report["picked"][0]["pareto_row"] == best and report["picked"][0]["bound_N"] == pytest.approx(bound)
    # the picked group's numbers, by brute force over the scripted worlds
    success, _, _ = expected(rollout, front.params[best][None], N_KNOWN + N_UNSEEN, 2, SCN.bt_hz)
    assert report["groups"]["picked"]["known"] == pytest.approx(success[0, :N_KNOWN].mean())
    assert report["groups"]["picked"]["unseen"] == pytest.approx(success[0, N_KNOWN:].mean())
    assert report["samples"]["picked"] == {"known": N_KNOWN, "unseen": N_UNSEEN}
    assert report["samples"]["random"] == {"known": 3 * N_KNOWN, "unseen": 3 * N_UNSEEN}
    rnd = expected(rollout, _random_sets(opt), N_KNOWN + N_UNSEEN, 2, SCN.bt_hz)[0]
    direct = mannwhitneyu(success[0, :N_KNOWN], rnd[:, :N_KNOWN].ravel(), alternative="two-sided").pvalue
    if np.ptp(np.concatenate([success[0, :N_KNOWN], rnd[:, :N_KNOWN].ravel()])) > 0:
        assert report["mann_whitney"]["random"]["known"] == pytest.approx(direct)
    assert report["front_size"]["mean"] == len(front) and report["front_size"]["sd"] is None  # one repetition


def _random_sets(run):
    from mjxskill.training.evaluate_run import load_evaluation

    ev, _ = load_evaluation(run)
    return ev.candidates.params[[g == "random" for g in ev.candidates.groups]]


def test_the_report_files_and_the_side_by_side_table(experiment):
    exp, _ = experiment
    for name in ("report.md", "report.json", "fronts.png", "hypervolume.png", "success.png"):
        assert (exp.path / name).stat().st_size > 1000, name
    text = (exp.path / "report.md").read_text()
    assert "1 of 2 repetitions finished (the report covers the finished ones)." in text
    assert "Protocol 2 repetitions x 8 evaluations x 2 worlds, smaller than the paper's 10 x 400 x 7." in text
    assert "| Pareto front size (mean over repetitions) | 8.3 |" in text
    assert "![success rates](success.png)" in text and "Rule: the Pareto solution with the highest training success" in text


def test_hypervolume_in_the_space_normalized_by_every_run():
    # larger is better: run a holds (1, 0) and (0, 1), run b (0.5, 0.5); negated and scaled by the
    # union they are (0, 1), (1, 0) and (0.5, 0.5); reference (1.1, 1.1)
    a = Evaluations(np.array([0, 0]), np.zeros((2, 1)), np.array([[1.0, 0.0], [0.0, 1.0]]), np.zeros(2), np.zeros(2))
    b = Evaluations(np.array([0]), np.zeros((1, 1)), np.array([[0.5, 0.5]]), np.zeros(1), np.zeros(1))
    lo, hi = normalization([a, b])
    np.testing.assert_array_equal(lo, [-1, -1]) and np.testing.assert_array_equal(hi, [0, 0])
    assert normalized_curve(a, lo, hi)[1][-1] == pytest.approx(2 * 1.1 * 0.1 - 0.01)  # two strips, overlap counted once
    assert normalized_curve(b, lo, hi)[1][-1] == pytest.approx(0.6 * 0.6)
    assert normalized_curve(b, lo, hi)[1][-1] == pytest.approx(hypervolume(np.array([[0.5, 0.5]]), [1.1, 1.1]))


def test_select_lists_the_runs_trained_so_far(experiment, capsys, tmp_path):
    from mjxskill.cli.select import main

    exp, _ = experiment
    assert main([str(exp.path), "--min-success", "0", "--no-render", "--out", str(tmp_path / "sel")]) == 0
    out = capsys.readouterr().out
    assert "Pareto fronts of the 3 trained runs in" in out and "random_search seed 5" not in out
    assert json.loads((tmp_path / "sel" / "parameters.json").read_text())["success_rate"] == 1.0
