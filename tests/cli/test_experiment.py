"""The real ``experiment`` command on a tiny push protocol (0.2 s episodes, 1 world, 2
repetitions of 4 evaluations): its directory and report, a kill and a resume that ends with the
same results, evaluate and select on the experiment, and bad input (one error line, exit 2)."""

import json
import signal
import subprocess
import time

import pytest

from cli_helpers import (QUICK_GP, ROOT, command, error_line, invoke, kill_once_written, run_cli, snapshot,
                         subprocess_env)
from mjxskill.runs.layout import runs_in

# The paper's protocol (validated picks); the robust one: tests/cli/test_robust.py.
TINY = ["--repeats", "2", "--budget", "4", "--batch-size", "2", "--init", "2", "--worlds", "1", "--episode-seconds", "0.2",
        "--per-config", "1", "--random", "1", "--quiet", "--protocol", "paper", "--confirm-per-config", "0",
        *(a for option in QUICK_GP for a in ("--optimizer-option", option))]
RESULTS = ("optimizer/seed-0/evaluations.csv", "optimizer/seed-1/evaluations.csv", "random_search/seed-0/evaluations.csv",
           "random_search/seed-1/evaluations.csv", "optimizer/seed-0/evaluation/evaluation.json",
           "optimizer/seed-1/evaluation/evaluation.json", "optimizer/seed-0/evaluation/validation.json",
           "optimizer/seed-1/evaluation/validation.json")


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    out = tmp_path_factory.mktemp("experiment") / "push-exp"
    done = run_cli("experiment", "push", *TINY, "--out", out)
    assert done.returncode == 0, done.stderr[-3000:]
    return out, done.stdout


def test_the_experiment_writes_every_repetition_and_the_report(experiment):
    out, stdout = experiment
    for text in ("experiment: 2 repetitions (seeds 0..1) of the optimizer and of random search",
                 "repetition 1 of 2 (seed 0): random search", "report of 1 of 2 repetitions", "report of 2 of 2 repetitions"):
        assert text in stdout
    assert [(r.kind, r.seed) for r in runs_in(out)] == [("optimizer", 0), ("optimizer", 1), ("random_search", 0), ("random_search", 1)]
    for name in RESULTS:
        assert (out / name).is_file(), name
    for r in runs_in(out):
        assert len((r.path / "evaluations.csv").read_text().splitlines()) == 1 + 4
    report = json.loads((out / "report.json").read_text())
    for key in ("task", "protocol", "front_size", "groups", "mann_whitney", "hypervolume"):
        assert key in report, key
    assert report["status"] == {"repetitions_done": 2, "repetitions": 2}
    assert set(report["front_size"]) >= {"mean", "sd"} and set(report["groups"]["random"]) == {"known", "unseen"}
    assert len(report["hypervolume"]["optimizer"]) == len(report["hypervolume"]["random_search"]) == 2
    assert set(report["mann_whitney"]) == {"pareto", "planner", "random", "manual"}
    times = json.loads((out / "state.json").read_text())["times"]
    assert set(times) == {f"{k}/seed-{s}" for k in ("optimizer", "random_search") for s in (0, 1)}
    assert all(t["train_seconds_evaluations"] == 4 for t in times.values())
    assert all("validate_seconds" in times[f"optimizer/seed-{s}"] for s in (0, 1))
    assert "repetition 2 of 2 (seed 1): validation of the pick" in stdout
    assert report["protocol"]["validation_per_config"] == 5 and report["training_pick"]["validated"]
    # no --max-force: push.yaml's pick.max_force, 10 N, with its reason, in the protocol and the report
    assert "pick bound 10 N (the scenario's pick.max_force)" in stdout
    assert report["protocol"]["max_force"] == 10.0 and report["protocol"]["max_force_source"].startswith(
        "the scenario's pick.max_force: The paper states no force limit")
    assert all(p["bound_N"] == 10.0 for p in report["picked"])
    assert "Bound: 10 N, the scenario's pick.max_force: The paper states no force limit" in (out / "report.md").read_text()
    assert all(p["validation_worlds"] == 5 * 4 for p in report["picked"])  # 4 known start configurations
    for name in ("report.md", "fronts.png", "hypervolume.png", "success.png"):
        assert (out / name).is_file()


def test_a_killed_experiment_resumes_to_the_same_results(experiment, tmp_path):
    out, _ = experiment
    cut = tmp_path / "cut"  # killed once the first random search has a batch on disk
    assert kill_once_written("experiment", ["push", *TINY, "--out", cut],
                             cut / "random_search" / "seed-0" / "evaluations.csv", 3)
    assert not (cut / "optimizer" / "seed-1" / "evaluation").exists()
    resumed = run_cli("experiment", "push", "--resume", cut, "--quiet")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    for name in RESULTS:
        assert (cut / name).read_text() == (out / name).read_text(), name
    a, b = (json.loads((d / "report.json").read_text()) for d in (out, cut))
    assert a["groups"] == b["groups"] and a["hypervolume"]["optimizer"] == b["hypervolume"]["optimizer"]


@pytest.mark.parametrize("how", [("experiment", "push", "--resume", "{copy}", "--quiet"), ("evaluate", "{copy}")])
def test_a_finished_experiment_may_pick_without_validation_and_retrains_nothing(experiment, tmp_path, how):
    import shutil

    out, _ = experiment
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    before = {n: (copy / n).read_text() for n in RESULTS}
    done = run_cli(*(a.format(copy=copy) for a in how), "--validation-per-config", "0")
    assert done.returncode == 0, done.stderr[-3000:]
    assert "the picks are now made by training success alone (no validation) (were after validating the 3 best " \
           "candidates in 5 worlds per known start configuration)" in done.stdout
    assert {n: (copy / n).read_text() for n in RESULTS} == before  # nothing retrained, evaluated or validated again
    report = json.loads((copy / "report.json").read_text())
    assert report["protocol"]["validation_per_config"] == 0 and report["training_pick"] == {"validated": False}
    assert report["pick_rule"].startswith("the Pareto solution with the highest training success rate")
    own = json.loads((out / "report.json").read_text())
    # the training-only picks are the ones the validated report names as such
    changed = {c["seed"]: c["training_row"] for c in own["training_pick"]["changed"]}
    assert [p["pareto_row"] for p in report["picked"]] == [changed.get(p["seed"], p["pareto_row"]) for p in own["picked"]]
    assert "validation_per_config: 0" in (copy / "experiment.yaml").read_text()


def test_ctrl_c_says_where_the_work_is_and_how_to_continue(tmp_path):
    cut = tmp_path / "interrupted"
    proc = subprocess.Popen(command("experiment", "push", *TINY, "--out", cut), cwd=ROOT, env=subprocess_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        target = cut / "optimizer" / "seed-0" / "evaluations.csv"
        deadline = time.monotonic() + 600
        while time.monotonic() < deadline and not (target.is_file() and len(target.read_text().splitlines()) >= 3):
            assert proc.poll() is None, "the experiment ended before it could be interrupted"
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr[-2000:]
    assert f"interrupted: every finished batch and evaluated chunk is in {cut}; continue with " \
           f"python -m mjxskill.experiment push --resume {cut}" in stderr
    assert "Traceback" not in stderr


def test_evaluate_and_select_take_the_experiment(experiment, capsys, tmp_path):
    out, _ = experiment
    before = {n: (out / n).read_text() for n in RESULTS}
    code, _ = invoke(capsys, "evaluate", out)
    assert code == 0
    assert {n: (out / n).read_text() for n in RESULTS} == before  # current evaluations reused
    code, _ = invoke(capsys, "select", out, "--no-render")
    assert code == 0
    code, _ = invoke(capsys, "select", out, "--pick", "0", "--no-render", "--out", tmp_path / "sel")
    assert code == 0
    doc = json.loads((tmp_path / "sel" / "parameters.json").read_text())
    assert doc["run"] == str(out / "optimizer" / "seed-0") and doc["pareto_index"] == 0


def test_select_takes_the_validated_solution_first(experiment, tmp_path, capsys):
    import shutil

    out, _ = experiment
    copy = tmp_path / "exp"
    shutil.copytree(out, copy)
    # the validations say: only seed 1's first contender succeeds in fresh worlds
    for seed in (0, 1):
        path = copy / "optimizer" / f"seed-{seed}" / "evaluation" / "validation.json"
        doc = json.loads(path.read_text())
        doc["success"] = [1.0 if (seed, i) == (1, 0) else 0.0 for i in range(len(doc["rows"]))]
        path.write_text(json.dumps(doc))
        if seed == 1:
            expected_row, worlds = doc["rows"][0], doc["worlds"]
    from mjxskill.select import main

    code = main([str(copy), "--min-success", "0", "--no-render", "--out", str(tmp_path / "sel")])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    header = next(line for line in printed.out.splitlines() if line.startswith("run "))
    assert header.rstrip().endswith("validated") and "(validated success 100%)" in printed.out
    doc = json.loads((tmp_path / "sel" / "parameters.json").read_text())
    assert doc["run"] == str(copy / "optimizer" / "seed-1") and doc["pareto_index"] == expected_row
    assert doc["validation_success_rate"] == 1.0 and doc["validated_in"].startswith(f"{worlds} fresh worlds")
    # the explore page's "select the best meeting them" follows the same rule
    from mjxskill.explore.data import choose_document, runs_in as page_runs

    entries = page_runs(copy)
    assert entries[1].run.path == copy / "optimizer" / "seed-1"
    assert choose_document(entries, None, 0.0) == {"run": 1, "k": expected_row}


def test_select_lists_without_a_damaged_or_stale_validation(experiment, tmp_path, capsys):
    import shutil

    import numpy as np

    from mjxskill.select import main
    from mjxskill.runs.run_dir import Run
    from mjxskill.evaluation.validation import validated_success

    out, _ = experiment
    copy = tmp_path / "exp"
    shutil.copytree(out, copy)
    seed0 = copy / "optimizer" / "seed-0" / "evaluation" / "validation.json"
    seed1 = copy / "optimizer" / "seed-1" / "evaluation" / "validation.json"
    # seed 1's first validated row no longer has the parameters it was validated with
    doc = json.loads(seed1.read_text())
    doc["params"][0] = [v + 1.0 for v in doc["params"][0]]
    seed1.write_text(json.dumps(doc))
    run = Run(copy / "optimizer" / "seed-1")
    rates, worlds, _ = validated_success(run, run.front(run.config()))
    assert np.isnan(rates[doc["rows"][0]]) and worlds == doc["worlds"]
    assert all(not np.isnan(rates[r]) for r in doc["rows"][1:])
    seed0.write_text("{not json")
    code = main([str(copy), "--no-render"])
    printed = capsys.readouterr()
    assert code == 0 and "Traceback" not in printed.err
    assert f"warning: {seed0} is not a readable validation" in printed.err and "listed without its validation" in printed.err
    assert "Pareto fronts of the" in printed.out


def test_evaluate_pools_a_repeated_run(experiment, tmp_path, capsys):
    import shutil

    out, _ = experiment
    rep = tmp_path / "rep"
    shutil.copytree(out / "optimizer", rep)
    code, stderr = invoke(capsys, "evaluate", rep, "--per-config", "1", "--random", "1")
    assert code == 0, stderr
    pooled = json.loads((rep / "evaluation" / "pooled.json").read_text())
    report = json.loads((out / "report.json").read_text())
    # the experiment evaluates repetition i in the worlds of its own seed, as evaluate does sub-run i with --seed 0
    assert pooled["groups"] == report["groups"] and pooled["mann_whitney"] == report["mann_whitney"]
    assert (rep / "evaluation" / "success.png").is_file()


BAD_INPUT = (
    (["experiment", "push", "--repeats", "0"], "argument --repeats: must be at least 1, got 0"),
    (["experiment", "push", "--per-config", "0"], "argument --per-config: must be at least 1"),
    (["experiment", "push", "--max-force", "-2"], "argument --max-force: must be a finite number >= 0"),
    (["experiment", "push", "--resume", "{exp}", "--budget", "9"], "drop --budget 9 (the run has 4)"),
    (["experiment", "push", "--resume", "{exp}", "--per-config", "7"], "drop --per-config 7 (the experiment has 1)"),
    (["experiment", "push", "--validation-per-config", "-1"], "argument --validation-per-config: must be at least 0, got -1"),
    (["experiment", "push", "--validation-candidates", "0"], "argument --validation-candidates: must be at least 1"),
    (["evaluate", "{exp}", "--validation-per-config", "0", "--validation-candidates", "2"],
     "picks without validation; give --validation-per-config N as well"),
    (["experiment", "push", "--resume", "{exp}", "--validation-per-config", "0", "--validation-candidates", "2"],
     "picks without validation; give --validation-per-config N as well"),
    (["experiment", "peg", "--resume", "{exp}", "--validation-per-config", "0"], "is a run of task 'push', not 'peg'"),
    (["experiment", "push", "--resume", "{run}"], "is not an experiment directory (no experiment.yaml)"),
    (["experiment", "peg", "--resume", "{exp}"], "is a run of task 'push', not 'peg'"),
    (["experiment", "push", "--out", "{exp}"], "already holds an experiment; continue it with --resume"),
    (["evaluate", "{exp}", "--seed", "3"], "each repetition is evaluated in the worlds of its own seed"),
    (["evaluate", "{exp}", "--per-config", "2"], "drop --per-config 2 (the experiment has 1)"),
    (["select", "{exp}", "--pick", "99"], "--pick 99: the fronts have rows 0-"),
    (["evaluate", "{exp}/optimizer"], "belongs to the experiment"),
    (["evaluate", "{run}", "--per-config", "2"], "belongs to the experiment"),
    (["evaluate", "{exp}/random_search/seed-1"], "copy"),
)


@pytest.mark.parametrize("case, message", BAD_INPUT)
def test_bad_input_is_one_message_and_changes_nothing(experiment, capsys, case, message):
    out, _ = experiment
    args = [a.format(exp=out, run=out / "optimizer" / "seed-0") for a in case]
    before = snapshot(out)
    code, stderr = invoke(capsys, *args)
    error_line(code, stderr, case[0], message)
    assert snapshot(out) == before
