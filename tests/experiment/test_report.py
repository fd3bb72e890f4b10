"""An experiment directory and its report, with hand-made training rows and a scripted rollout in
place of the physics: which runs it holds, which repetitions are finished, the pick, the pooled
groups and tests, the normalized hypervolume and front sizes, report.json and report.md."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.stats import mannwhitneyu

from mjxskill.errors import RunError
from mjxskill.gp import hypervolume
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task, planning_texts
from mjxskill.evaluation.evaluate_run import evaluate_run
from mjxskill.experiment.directory import Experiment, Protocol
from mjxskill.experiment.report import write_report
from mjxskill.experiment.directory import repetition_settings
from mjxskill.experiment.driver import validate_timed
from mjxskill.experiment.stats import normalization, normalized_curve
from mjxskill.training.front import pareto_mask_of
from mjxskill.runs.run_dir import Evaluations, RunConfig, batch_sizes
from mjxskill.runs.layout import directory_kind, runs_in
from cli_helpers import error_line, invoke, snapshot
from scripted import ScriptedRollout, expected

SCN = load_scenario("push")
TASK = plan_task(SCN)
N_KNOWN, N_UNSEEN = len(SCN.robot.start_configs), len(SCN.robot.eval_configs)
CONFIG = RunConfig(task="push", scenario="push", goal=TASK.goal, parameter_names=TASK.parameter_names,
                   parameter_units=TASK.parameter_units, bounds=tuple(tuple(map(float, b)) for b in TASK.bounds),
                   objective_names=SCN.objective_names, budget=8, batch_size=3, n_init=3, worlds=2, seed=5,
                   episode_seconds=0.2, repeats=2, engine="native")
BOUND_WHY = "the scenario's pick.max_force: half the training rows' commanded forces"
PROTOCOL = Protocol(per_config=2, random_sets=3, max_force=0.8, validation_per_config=2, validation_candidates=3,
                    max_force_source=BOUND_WHY)


def training_rows(seed: int, kind: int) -> Evaluations:
    """A full budget of rows in the run's batches, reproducible from (seed, kind)."""
    rng = np.random.default_rng([seed, kind])
    sizes = list(batch_sizes(CONFIG.budget, CONFIG.batch_size, CONFIG.n_init))
    n = sum(sizes)
    lo, hi = np.asarray(CONFIG.bounds)
    params, objectives = lo + rng.random((n, 4)) * (hi - lo), rng.normal(size=(n, 2)) * [100, 10] + [500, 100]
    success, force = rng.integers(0, 3, n) / 2, rng.random(n) * 1.6  # force: the commanded one
    return Evaluations(np.repeat(np.arange(len(sizes)), sizes), params, objectives, success, 1.5 * force, force / 2, force)


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
        validate_timed(exp, opt, rollout, CONFIG, PROTOCOL, CONFIG.seed + i)
    write_report(exp)
    return exp, rollout


def test_the_explore_page_shows_an_experiments_runs_in_its_order(experiment):
    from mjxskill.explore.data import runs_in as page_runs

    exp, _ = experiment
    entries = page_runs(exp.path)
    # every optimizer repetition, then the random searches that have a config (all do: create
    # writes them whole); the labels say which kind each is
    assert [(e.label, e.run.path) for e in entries] == [
        (f"{kind} seed {r.seed}", r.path) for r, kind in
        zip(runs_in(exp.path), ["optimizer", "optimizer", "random search", "random search"])]


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


def test_the_planning_files_are_written_once_at_the_experiments_root(experiment):
    exp, _ = experiment
    planning = ("domain.pddl", "problem.pddl", "plan.txt", "bt.txt")
    # nowhere below the root: not in optimizer/ or random_search/, not in a seed's run
    assert sorted(p.relative_to(exp.path).as_posix() for name in planning for p in exp.path.rglob(name)) == sorted(planning)
    on_disk = {name: (exp.path / name).read_text() for name in planning}
    # the planned task, each file ended by one newline
    assert on_disk["domain.pddl"].rstrip("\n") == TASK.domain_pddl.rstrip("\n")
    assert on_disk["problem.pddl"].rstrip("\n") == TASK.problem_pddl.rstrip("\n")
    assert on_disk["plan.txt"] == f"; goal: {TASK.goal}\n" + "\n".join(TASK.plan) + "\n"
    assert {name: text.rstrip("\n") for name, text in on_disk.items()} == {
        name: text.rstrip("\n") for name, text in planning_texts(TASK).items()}
    assert all(text.endswith("\n") and not text.endswith("\n\n") for text in on_disk.values())


def test_the_report_covers_the_finished_repetitions_with_the_stated_pick(experiment):
    exp, rollout = experiment
    report = json.loads((exp.path / "report.json").read_text())
    assert report["task"] == "push" and report["status"] == {"repetitions_done": 1, "repetitions": 2}
    protocol = report["protocol"]
    for key, value in dict(budget=8, batch_size=3, n_init=3, worlds=2, seed=5, repeats=2, engine="native",
                           per_config=2, random_sets=3, max_force=0.8, max_force_source=BOUND_WHY,
                           known_configs=N_KNOWN, unseen_configs=N_UNSEEN).items():
        assert protocol[key] == value, key
    # the pick, by hand: the highest training success within the stated 0.8 N of commanded force
    opt = exp.optimizer.sub_runs(CONFIG)[1]
    front = opt.front(opt.config())
    assert report["picked"][0]["seed"] == 6
    bound = 0.8
    assert report["picked"][0]["bound_source"] == BOUND_WHY
    ok = front.peak_commanded_force <= bound  # the commanded force, not the measured contact force
    assert not ok.all() and front.success_rate[~ok].max() == 1  # the bound excludes a fully successful solution
    # the three best in training, validated in 2 worlds from each known configuration (the
    # scripted worlds do not depend on the key: those are worlds r = 0, 1 of each known one)
    contenders = sorted(np.flatnonzero(ok), key=lambda k: (-front.success_rate[k], -front.objectives[k, 0]))[:3]
    validation = expected(rollout, front.params[contenders], N_KNOWN, 2, SCN.bt_hz)[0].mean(axis=1)
    best = max(contenders, key=lambda k: (validation[contenders.index(k)], front.success_rate[k], front.objectives[k, 0]))
    assert report["picked"][0]["pareto_row"] == best and report["picked"][0]["bound_N"] == pytest.approx(bound)
    assert report["picked"][0]["validation_rates"] == {str(k): pytest.approx(v) for k, v in zip(contenders, validation)}
    assert report["picked"][0]["validation_worlds"] == 2 * N_KNOWN
    assert report["protocol"]["validation_per_config"] == 2 and report["protocol"]["validation_candidates"] == 3
    # what the training success alone picks, and whether that differs
    changed = [] if best == contenders[0] else [{"seed": 6, "validated_row": best, "training_row": contenders[0]}]
    assert report["training_pick"]["validated"] and report["training_pick"]["changed"] == changed
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
    # time to success by brute force over the scripted worlds: per world the time or None (failed)
    def times(p):
        return [(t + 1) / SCN.bt_hz if ok else None for c in range(N_KNOWN + N_UNSEEN) for r in range(2)
                for ok, _, t in [rollout.outcome(p, c, r)]]

    mine = times(front.params[best])
    operators = [times(np.array([m.values[n] for n in TASK.parameter_names])) for m in SCN.manual_parameters.values()]
    pairs = [(a, b) for op in operators for a, b in zip(mine, op) if a is not None and b is not None]
    t = report["time_to_success"]
    assert t["paired"] == pytest.approx({"picked_s": np.mean([a for a, _ in pairs]), "operators_s": np.mean([b for _, b in pairs]),
                                         "paired_worlds": len(pairs)})
    full = lambda ts: np.mean([CONFIG.episode_seconds if x is None else x for x in ts])  # noqa: E731
    assert t["full_episode"] == pytest.approx({"picked_s": full(mine), "operators_s": full(sum(operators, []))})
    paired, whole = [row for row in report["paper"] if "faster" in row["quantity"]]
    assert "where both succeed" in paired["quantity"]
    assert paired["ours"] == pytest.approx(1 - t["paired"]["picked_s"] / t["paired"]["operators_s"])
    assert "full 0.2 s episode" in whole["quantity"] and whole["ours"] == pytest.approx(1 - full(mine) / full(sum(operators, [])))


def _random_sets(run):
    from mjxskill.evaluation.evaluate_run import load_evaluation

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
    assert "![success rates](success.png)" in text
    assert "Rule: of the Pareto solutions whose commanded force" in text and f"rolled out again in {2 * N_KNOWN} fresh worlds" in text
    assert "| training success | validation success |" in text
    assert f"Bound: 0.8 N, {BOUND_WHY}" in text  # the bound and where it comes from
    assert "### The picked success against the force bound" in text and "| 0.8 N (used) | 1 of 1 |" in text
    assert "operators (illustrative)" in text and "not the paper's operators', whose sets are unpublished" in text


def test_hypervolume_in_the_space_normalized_by_every_run():
    # larger is better: run a holds (1, 0) and (0, 1), run b (0.5, 0.5); negated and scaled by the
    # union they are (0, 1), (1, 0) and (0.5, 0.5); reference (1.1, 1.1)
    a = Evaluations(np.array([0, 0]), np.zeros((2, 1)), np.array([[1.0, 0.0], [0.0, 1.0]]), *np.zeros((4, 2)))
    b = Evaluations(np.array([0]), np.zeros((1, 1)), np.array([[0.5, 0.5]]), *np.zeros((4, 1)))
    lo, hi = normalization([a, b])
    np.testing.assert_array_equal(lo, [-1, -1])
    np.testing.assert_array_equal(hi, [0, 0])
    assert normalized_curve(a, lo, hi)[1][-1] == pytest.approx(2 * 1.1 * 0.1 - 0.01)  # two strips, overlap counted once
    assert normalized_curve(b, lo, hi)[1][-1] == pytest.approx(0.6 * 0.6)
    assert normalized_curve(b, lo, hi)[1][-1] == pytest.approx(hypervolume(np.array([[0.5, 0.5]]), [1.1, 1.1]))


def test_select_lists_the_runs_trained_so_far(experiment, capsys, tmp_path):
    from mjxskill.cli.select import main

    exp, _ = experiment
    assert main([str(exp.path), "--min-success", "0", "--no-render", "--out", str(tmp_path / "sel")]) == 0
    out = capsys.readouterr().out
    assert "Pareto fronts of the 3 trained runs in" in out and "random_search seed 5" not in out
    # a validated solution goes first: the pick has the highest validation success of every run's
    # validation.json (the solution with 100 % training success is not it)
    doc = json.loads((tmp_path / "sel" / "parameters.json").read_text())
    validations = {p.parents[1]: json.loads(p.read_text()) for p in exp.path.glob("*/seed-*/evaluation/validation.json")}
    assert validations
    best = max(max(v["success"]) for v in validations.values())
    own = validations[Path(doc["run"])]
    assert own["success"][own["rows"].index(doc["pareto_index"])] == best
    assert "(validated success" in out


def test_report_json_holds_the_fields_the_issue_names_as_plain_data(experiment):
    exp, _ = experiment

    def no_nan(name):
        raise AssertionError(f"report.json holds {name}: not plain JSON")

    report = json.loads((exp.path / "report.json").read_text(), parse_constant=no_nan)
    done = report["status"]["repetitions_done"]
    assert report["task"] == "push"
    # protocol: every setting of train and of the evaluation, as stored in the run and the experiment
    settings = {"task", "goal", "scenario", "budget", "batch_size", "n_init", "worlds", "seed", "episode_seconds",
                "repeats", "engine", "optimizer_options", "per_config", "random_sets", "max_force",
                "known_configs", "unseen_configs", "parameters", "objectives"}
    assert settings <= set(report["protocol"]), settings - set(report["protocol"])
    assert set(report["protocol"]["parameters"]) == set(TASK.parameter_names)
    assert set(report["front_size"]) >= {"mean", "sd"}
    assert isinstance(report["front_size"]["mean"], float) and report["front_size"]["sd"] is None  # sd of 1: none
    groups = report["groups"]
    assert set(groups) == {"picked", "pareto", "planner", "random", "manual"}
    for name, rates in groups.items():
        assert set(rates) == {"known", "unseen"} and all(0 <= v <= 1 for v in rates.values()), name
    assert set(report["mann_whitney"]) == {"pareto", "planner", "random", "manual"}  # picked vs each
    for name, tests in report["mann_whitney"].items():
        assert set(tests) == {"known", "unseen"} and all(0 < p <= 1 for p in tests.values()), name
    hv = report["hypervolume"]
    assert len(hv["optimizer"]) == len(hv["random_search"]) == done
    assert all(0 <= v <= 1.1 ** 2 for v in hv["optimizer"] + hv["random_search"])
    assert [len(c) for c in hv["curves"]["optimizer"]] == [len(hv["evaluations"])] * done
    assert hv["evaluations"][-1] == CONFIG.budget
    assert set(report["wall_time"]) == {"6"} and set(report["wall_time"]["6"]) == {"optimizer", "random_search"}
    assert [row["paper"] for row in report["paper"]][0] == 8.3  # push front size


# Samples whose Mann-Whitney p (scipy) falls in each band of the paper's four levels.
PICKED = np.array([1.0, 1.0, 1.0, 0.5, 1.0, 0.5, 1.0, 1.0, 0.5, 1.0, 0.0, 1.0])


def _baseline(ones: int) -> np.ndarray:
    rest = 12 - ones
    return np.array([1.0] * ones + [0.5] * (rest // 2) + [0.0] * (rest - rest // 2))


BANDS = {  # (group, side) -> (baseline sample, expected stars)
    ("pareto", "known"): (_baseline(8), "ns"),
    ("planner", "known"): (_baseline(4), "*"),
    ("random", "known"): (_baseline(3), "**"),
    ("manual", "known"): (_baseline(1), "***"),
    ("pareto", "unseen"): (np.zeros(12), "****"),
    ("planner", "unseen"): (_baseline(12), "**"),
    ("random", "unseen"): (_baseline(2), "**"),
    ("manual", "unseen"): (PICKED.copy(), "ns"),  # identical samples: no difference
}


def _band(p: float) -> str:
    """The paper's levels written out: * p < 0.1, ** p < 0.05, *** p < 0.01, **** p < 0.001."""
    return "****" if p < 0.001 else "***" if p < 0.01 else "**" if p < 0.05 else "*" if p < 0.1 else "ns"


def test_mann_whitney_stars_at_the_four_levels_agree_with_scipy(experiment, tmp_path):
    from mjxskill.experiment.report import markdown
    from mjxskill.evaluation.pooled import POOLED_LABELS, plot_pooled, pooled_tests

    samples = {"picked": (PICKED, PICKED)}
    for group in ("pareto", "planner", "random", "manual"):
        samples[group] = (BANDS[(group, "known")][0], BANDS[(group, "unseen")][0])
    tests = pooled_tests(samples)
    plotted = plot_pooled(samples, tmp_path / "success.png", "bands")
    exp, _ = experiment
    summary = json.loads((exp.path / "report.json").read_text())
    summary.update(mann_whitney=tests, groups={g: {"known": float(k.mean()), "unseen": float(u.mean())} for g, (k, u) in samples.items()},
                   samples={g: {"known": len(k), "unseen": len(u)} for g, (k, u) in samples.items()})
    text = markdown(summary)
    for (group, side), (baseline, stars) in BANDS.items():
        p = mannwhitneyu(PICKED, baseline, alternative="two-sided").pvalue if np.ptp(np.r_[PICKED, baseline]) else 1.0
        assert _band(p) == stars, (group, side, p)  # the samples are in the band they are meant for
        assert tests[group][side] == pytest.approx(p), (group, side)
        assert plotted[(side, POOLED_LABELS[group])] == (pytest.approx(p), stars)  # the box plot's stars
        row = next(line for line in text.splitlines() if line.startswith(f"| {POOLED_LABELS[group]} |"))
        assert f"| {p:.3g} {stars} |" in row, (row, p, stars)
    assert {stars for _, stars in BANDS.values()} == {"ns", "*", "**", "***", "****"}


def _rows(*batches) -> Evaluations:
    """Evaluations from batches of objective rows (larger is better)."""
    objectives = np.array([row for batch in batches for row in batch], np.float64)
    iteration = np.concatenate([np.full(len(b), i) for i, b in enumerate(batches)])
    n = len(objectives)
    return Evaluations(iteration, np.zeros((n, 1)), objectives, *np.zeros((4, n)))


def test_hypervolume_of_repetitions_is_taken_in_the_space_of_their_union():
    from mjxskill.experiment.stats import Repetition, hypervolumes

    # objective 0 spans [0, 3] and objective 1 [0, 4] over the four runs together (no single run
    # spans both): scaled minimized point s = ((3 - o0) / 3, (4 - o1) / 4), reference (1.1, 1.1)
    runs = {"opt-0": _rows([(2, 0)], [(0, 4)]), "rnd-0": _rows([(1, 2)], [(0, 0)]),
            "opt-1": _rows([(3, 4)], [(1, 1)]), "rnd-1": _rows([(1, 3)], [(0.5, 2)])}
    reps = [Repetition(0, runs["opt-0"], runs["rnd-0"], None, None, None),
            Repetition(1, runs["opt-1"], runs["rnd-1"], None, None, None)]
    hv = hypervolumes(reps)
    assert hv["normalization"] == {"min": [-3.0, -4.0], "max": [0.0, 0.0]} and hv["reference_point"] == [1.1, 1.1]
    box = lambda s0, s1: (1.1 - s0) * (1.1 - s1)  # noqa: E731  the region one point dominates
    # opt-0: (1/3, 1) then (1, 0), overlapping in [1, 1.1]^2; rnd-0: (2/3, 1/2), then (1, 1) dominated;
    # opt-1: (0, 0) at once; rnd-1: (2/3, 1/4), then (5/6, 1/2) dominated
    first = box(1 / 3, 1)
    expected = {"opt-0": [first, first + box(1, 0) - 0.01], "rnd-0": [box(2 / 3, 0.5)] * 2,
                "opt-1": [1.21, 1.21], "rnd-1": [box(2 / 3, 0.25)] * 2}
    assert hv["evaluations"] == [1, 2]
    for i in (0, 1):
        np.testing.assert_allclose(hv["curves"]["optimizer"][i], expected[f"opt-{i}"])
        np.testing.assert_allclose(hv["curves"]["random_search"][i], expected[f"rnd-{i}"])
        assert hv["optimizer"][i] == pytest.approx(expected[f"opt-{i}"][-1])
        assert hv["random_search"][i] == pytest.approx(expected[f"rnd-{i}"][-1])
    assert hv["mann_whitney_p_final"] == pytest.approx(
        mannwhitneyu(hv["optimizer"], hv["random_search"], alternative="two-sided").pvalue)
    # the first repetition alone spans objective 0 over [0, 2] only: its own space gives other numbers
    alone = hypervolumes(reps[:1])
    assert alone["optimizer"][0] == pytest.approx(box(0, 1) + box(1, 0) - 0.01)
    assert alone["optimizer"][0] != pytest.approx(hv["optimizer"][0])
    assert hypervolumes([]) == {"optimizer": [], "random_search": []}


def test_the_bound_sweep_picks_again_at_each_bound_from_what_the_experiment_has():
    from mjxskill.evaluation.validation import Validation
    from mjxskill.experiment.stats import Repetition, bound_sweep, sweep_bounds
    from toy_evaluations import front_of, toy_evaluation

    # three Pareto rows commanding 2, 5 and 9 N, 50, 80 and 100 % in training; evaluated at
    # 100 % (row 0), 50 % known / 0 % unseen (row 1), 25 % / 100 % (row 2); the validation rolled
    # out the two contenders within 10 N (rows 2 and 1: 20 % and 90 %)
    ev = toy_evaluation(np.array([[1.0, 1.0, 1.0], [0.5, 0.5, 0.0], [0.0, 0.5, 1.0]]), manual_force=[4.0])
    front = front_of(ev, [0.5, 0.8, 1.0], [2.0, 5.0, 9.0], [1.0, 2.0, 3.0])
    validation = Validation((2, 1), np.array([0.2, 0.9]), 20, 2, np.array([6.0, 7.0]))
    rep = Repetition(0, None, None, front, ev, None, validation, None)
    protocol = Protocol(max_force=10.0, validation_per_config=5, validation_candidates=2, max_force_source="stated")
    assert sweep_bounds(10.0, [front]) == [2.0, 4.0, 6.0, 8.0, 10.0]  # fifths of 10 N (above the fronts' 9 N)
    assert sweep_bounds(3.0, [front]) == [1.8, 3.0, 3.6, 5.4, 7.2, 9.0]  # the bound among fifths of the fronts' 9 N
    rows = {r["bound_N"]: r for r in bound_sweep([rep], protocol)}
    # by hand: within 2 or 4 N only row 0 (not validated: its training success picks it); within
    # 6 or 8 N rows 1 and 0, row 1 the better in training (row 0 never validated); within 10 N
    # the validated contenders 2 and 1: row 1, 90 % against 20 %
    for bound, (known, unseen, force, validated) in {2.0: (1.0, 1.0, 2.0, 0), 4.0: (1.0, 1.0, 2.0, 0),
                                                     6.0: (0.5, 0.0, 5.0, 0), 8.0: (0.5, 0.0, 5.0, 0),
                                                     10.0: (0.5, 0.0, 5.0, 1)}.items():
        r = rows[bound]
        assert (r["known"], r["unseen"], r["mean_commanded_force_N"], r["validated"]) == (known, unseen, force, validated), bound
        assert r["repetitions_with_pick"] == 1 and r["used"] == (bound == 10.0)
    assert bound_sweep([rep], replace(protocol, max_force=1.0))[0]["repetitions_with_pick"] == 0  # nothing within 1 N


GOOD_PROTOCOL = "format: mjxskill.experiment/1\ntask: push\nper_config: 2\nrandom_sets: 3\nmax_force: null\n"
DAMAGED = (  # (file, its text, what the one error line says)
    ("experiment.yaml", GOOD_PROTOCOL.replace("per_config: 2", "per_config: 0"),
     "experiment.yaml: per_config (line 3): expected an integer >= 1, got 0"),
    ("experiment.yaml", GOOD_PROTOCOL.replace("max_force: null", "max_force: -1"),
     "experiment.yaml: max_force (line 5): expected a number >= 0, got -1"),
    ("experiment.yaml", GOOD_PROTOCOL.replace("max_force: null\n", ""), "experiment.yaml: <top level> (line 1): missing key 'max_force'"),
    ("experiment.yaml", GOOD_PROTOCOL + "validation_per_config: -1\n",
     "experiment.yaml: validation_per_config (line 6): expected an integer >= 0, got -1"),
    ("experiment.yaml", GOOD_PROTOCOL.replace("mjxskill.experiment/1", "other"),
     "experiment.yaml: format (line 1): not an mjxskill experiment"),
    ("experiment.yaml", "format: mjxskill.experiment/1\nper_config: [\n", "experiment.yaml (line 3, column 1): not valid YAML"),
    ("state.json", "{not json", "state.json is not an experiment state"),
    # wrong types: the report formats them (a TypeError after report.json was rewritten)
    ("state.json", '{"sessions": [{"started": "x", "startup_seconds": "slow", "engine": "native", "cpus": 2}], "times": {}}',
     "state.json is not an experiment state (sessions[0].startup_seconds is 'slow')"),
    ("state.json", '{"sessions": [], "times": {"optimizer/seed-0": {"train_seconds": [1e999]}}}',
     "state.json is not an experiment state (times.optimizer/seed-0.train_seconds is [inf]"),
)


def test_an_experiment_written_before_validation_picks_by_training_success():
    from mjxskill.experiment.stats import pick_rule

    old = Protocol.from_yaml(GOOD_PROTOCOL, "experiment.yaml")
    assert (old.validation_per_config, old.per_config, old.random_sets) == (0, 2, 3)
    assert pick_rule(old, 4).startswith("the Pareto solution with the highest training success rate")
    assert Protocol.from_yaml(PROTOCOL.to_yaml("push"), "experiment.yaml") == PROTOCOL  # round trip


def test_an_experiment_whose_bound_was_the_operators_gets_the_scenarios(experiment, tmp_path):
    import shutil

    exp, _ = experiment
    copy = Experiment(tmp_path / "exp")
    shutil.copytree(exp.path, copy.path)
    # written before the bound was stated: null meant the largest force an operator set commands
    legacy = PROTOCOL.to_yaml("push").replace("max_force: 0.8", "max_force: null")
    (copy.path / "experiment.yaml").write_text(legacy[: legacy.index("max_force_source")])
    assert copy.protocol().max_force is None and copy.protocol().max_force_source is None
    protocol, said = copy.settle_bound(SCN.pick)
    assert protocol.max_force == 10.0 and protocol.max_force_source == f"the scenario's pick.max_force: {SCN.pick.why}"
    assert "was the largest force an operator set commands; it is now 10 N" in said and "evaluations are kept" in said
    assert copy.protocol() == protocol  # written back
    assert copy.settle_bound(SCN.pick) == (protocol, None)  # settled once
    # a number written before the source was kept was --max-force's
    given = Protocol.from_yaml(legacy[: legacy.index("max_force_source")].replace("max_force: null", "max_force: 3"), "x")
    assert (given.max_force, given.max_force_source) == (3.0, "given (--max-force)")


def damaged_copy(experiment, tmp_path, name, text):
    """A copy of the finished experiment with ``name`` replaced by ``text``, and its snapshot."""
    exp, _ = experiment
    copy = tmp_path / "exp"
    shutil.copytree(exp.path, copy)
    (copy / name).write_text(text)
    return copy, snapshot(copy)


@pytest.mark.parametrize("name, text, message", DAMAGED)
def test_a_damaged_experiment_file_is_one_error_line_naming_file_key_and_line(experiment, tmp_path, capsys, name, text, message):
    copy, before = damaged_copy(experiment, tmp_path, name, text)
    code, stderr = invoke(capsys, "experiment", "push", "--resume", copy)
    error_line(code, stderr, "experiment", str(copy / name), message)
    assert snapshot(copy) == before


@pytest.mark.parametrize("name, text, message", [case for case in DAMAGED if case[0] == "state.json"])
def test_evaluate_refuses_a_damaged_state_before_the_report_is_rewritten(experiment, tmp_path, capsys, name, text, message):
    copy, before = damaged_copy(experiment, tmp_path, name, text)
    code, stderr = invoke(capsys, "evaluate", copy)
    error_line(code, stderr, "evaluate", str(copy / name), message)
    assert snapshot(copy) == before  # report.json and report.md included


@pytest.mark.parametrize("args, message", (
    (["push", "--optimizer", "random"], "the experiment runs both the optimizer and random search; drop --optimizer random"),
    (["push", "--repeats", "x"], "argument --repeats: expected an integer, got 'x'"),
    (["push", "--random", "-1"], "argument --random: must be at least 0, got -1"),
    (["push", "--seed", "-1"], "argument --seed:"),
    (["nosuch"], "unknown task 'nosuch'"),
    (["push", "--resume", "{tmp}/missing"], "missing is not an experiment directory (no experiment.yaml)"),
))
def test_bad_flags_are_one_error_line_before_anything_runs(tmp_path, capsys, args, message):
    code, stderr = invoke(capsys, "experiment", *(a.format(tmp=tmp_path) for a in args))
    error_line(code, stderr, "experiment", message)
    assert list(tmp_path.iterdir()) == []


def test_experiment_holding_knows_the_members_as_written_and_through_links(tmp_path):
    from mjxskill.runs.layout import EXPERIMENT, experiment_holding

    exp = tmp_path / "exp"
    (exp / "optimizer" / "seed-0").mkdir(parents=True)
    (exp / "random_search").mkdir()
    (exp / EXPERIMENT).write_text("per_config: 1\n")
    assert experiment_holding(exp / "optimizer").resolve() == exp.resolve()
    assert experiment_holding(exp / "optimizer" / "seed-0").resolve() == exp.resolve()
    assert experiment_holding(exp / "random_search").resolve() == exp.resolve()
    assert experiment_holding(exp) is None  # the experiment itself is evaluated as one
    # a link to a member, and a member that is a link to storage elsewhere
    (tmp_path / "shortcut").symlink_to(exp / "optimizer" / "seed-0")
    assert experiment_holding(tmp_path / "shortcut").resolve() == exp.resolve()
    elsewhere = tmp_path / "storage" / "opt"
    (elsewhere / "seed-0").mkdir(parents=True)
    other = tmp_path / "exp2"
    other.mkdir()
    (other / EXPERIMENT).write_text("per_config: 1\n")
    (other / "optimizer").symlink_to(elsewhere)
    assert experiment_holding(other / "optimizer" / "seed-0") is not None
    # a run of one's own named like a member, with no experiment beside it
    (tmp_path / "mine" / "optimizer").mkdir(parents=True)
    assert experiment_holding(tmp_path / "mine" / "optimizer") is None
