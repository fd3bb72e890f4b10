"""The real commands in subprocesses: a tiny push training (0.2 s episodes, 1 world) with two
repeats, a run killed after its first batch and resumed, select's export, and bad input
(exit code 2, one message line, no traceback)."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from cli_helpers import TINY, invoke, kill_once_written, run_cli
from mjxskill.runs.run_dir import EVALUATIONS, PARETO, Run
from mjxskill.task import plan_task


@pytest.fixture(scope="session")
def repeated_run(tmp_path_factory):
    """``train push --repeats 2 --seed 1`` on a tiny budget: sub-runs seed-1 and seed-2."""
    out = tmp_path_factory.mktemp("train") / "push-x2"
    done = run_cli("train", "push", *TINY, "--seed", "1", "--repeats", "2", "--out", out)
    assert done.returncode == 0, done.stderr[-3000:]
    return out, done.stdout


def test_train_prints_the_pipeline_and_writes_the_run_directory(repeated_run):
    out, stdout = repeated_run
    for text in ("goal: (skiros:at", "plan:", "behavior tree:", "learnable parameters (4",
                 "objectives (larger is better): success, applied_force", "mean Pareto front size"):
        assert text in stdout
    from mjxskill import load_scenario

    scn = load_scenario("push")
    for name, lo, hi, unit in zip(plan_task(scn).parameter_names, *plan_task(scn).bounds, plan_task(scn).parameter_units):
        line = next(line for line in stdout.splitlines() if line.strip().startswith(name + " "))
        assert f"[{lo:g}, {hi:g}] {unit}" in line
    assert (out / "pareto_runs.png").is_file()
    sizes = yaml.safe_load((out / "repeats.yaml").read_text())
    for seed in (1, 2):
        sub = out / f"seed-{seed}"
        for name in ("config.yaml", "scenario.yaml", "domain.pddl", "problem.pddl", "plan.txt", "bt.txt",
                     EVALUATIONS, PARETO, "pareto.png", "hypervolume.png", "optimizer_state.npz"):
            assert (sub / name).is_file(), name
        run = Run(sub)
        config = run.config()
        assert (config.seed, config.repeats, config.worlds) == (seed, 1, 1)
        ev = run.evaluations()
        assert list(ev.iteration) == [0, 0, 0, 1, 1, 1]
        assert np.all((ev.success_rate >= 0) & (ev.success_rate <= 1)) and np.all(np.isfinite(ev.objectives))
        assert sizes["pareto_sizes"][seed] == len(run.pareto())
    assert sizes["mean_pareto_size"] == np.mean(list(sizes["pareto_sizes"].values()))
    first, second = (Run(out / f"seed-{s}").evaluations() for s in (1, 2))
    assert not np.array_equal(first.params, second.params)  # independent seeds


def test_killed_run_resumes_to_the_same_results(repeated_run, tmp_path):
    out, _ = repeated_run
    cut = tmp_path / "cut"
    assert kill_once_written("train", ["push", *TINY, "--seed", "1", "--out", cut], cut / EVALUATIONS, 4)
    assert 3 <= len(Run(cut).evaluations()) < 6
    resumed = run_cli("train", "push", "--resume", cut, "--quiet")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    reference = out / "seed-1"
    assert (cut / EVALUATIONS).read_text() == (reference / EVALUATIONS).read_text()
    assert (cut / PARETO).read_text() == (reference / PARETO).read_text()


def test_the_engine_is_a_run_setting(repeated_run, tmp_path):
    out, stdout = repeated_run
    assert "engine: native (auto: the native engine on the CPU" in stdout  # what auto picks here
    assert yaml.safe_load((out / "seed-1" / "config.yaml").read_text())["engine"] == "native"
    mjx = tmp_path / "mjx"
    done = run_cli("train", "push", *TINY, "--budget", "3", "--seed", "1", "--engine", "mjx", "--out", mjx)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "engine: mjx (as asked)" in done.stdout
    assert yaml.safe_load((mjx / "config.yaml").read_text())["engine"] == "mjx"
    # the same worlds and parameters on the other engine: the warm-up rows agree on what is discrete
    native, compiled = Run(out / "seed-1").evaluations(), Run(mjx).evaluations()
    np.testing.assert_array_equal(native.params[:3], compiled.params[:3])
    np.testing.assert_array_equal(native.success_rate[:3], compiled.success_rate[:3])
    np.testing.assert_allclose(native.objectives[:3], compiled.objectives[:3], rtol=2e-3)


def test_select_exports_the_picked_solution(repeated_run, tmp_path):
    out, _ = repeated_run
    sub = out / "seed-1"
    front = Run(sub).pareto()
    done = run_cli("select", sub, "--pick", "0", "--no-render", "--out", tmp_path / "sel")
    assert done.returncode == 0, done.stderr
    doc = yaml.safe_load((tmp_path / "sel" / "parameters.yaml").read_text())
    values = [doc["parameters"][n]["value"] for n in Run(sub).config().parameter_names]
    np.testing.assert_array_equal(values, front.params[0])
    assert doc["parameters"]["Push.offset_x_start"]["unit"] == "m"
    import json

    assert json.loads((tmp_path / "sel" / "parameters.json").read_text()) == doc


def bad_scenario(tmp_path) -> Path:
    from scenario_texts import shipped_text

    text = shipped_text("push").replace("bt_hz: 10", "bt_hz: -3")
    assert "bt_hz: -3" in text
    path = tmp_path / "broken.yaml"
    path.write_text(text)
    return path


BAD_INPUT = (
    (["train", "nosuchtask"], "unknown task 'nosuchtask'"),
    (["train", "push", "--budget", "0"], "argument --budget: must be at least 1, got 0"),
    (["train", "push", "--worlds", "many"], "argument --worlds: expected an integer, got 'many'"),
    (["train", "push", "--episode-seconds", "nan"], "argument --episode-seconds: must be a positive finite number"),
    (["train", "push", "--budget", "6", "--init", "10"], "--init 10 exceeds the 5 evaluations the robust protocol "
                                                         "trains with of the budget of 6 (the race has the rest)"),
    (["train", "push", "--budget", "6", "--init", "10", "--protocol", "paper"], "--init 10 exceeds the budget of 6 evaluations"),
    (["train", "push", "--optimizer-option", "n_rwa=3"], "--optimizer-option: unknown acquisition setting 'n_rwa'; valid settings: scalarization, alpha,"),
    (["train", "push", "--optimizer-option", "n_raw=0"], "--optimizer-option: acquisition setting n_raw: expected a positive integer"),
    (["train", "push", "--resume", "{tmp}"], "is not a run directory"),
    (["train", "peg", "--resume", "{run}"], "is a run of task 'push', not 'peg'"),
    (["train", "push", "--resume", "{run}", "--budget", "9"], "drop --budget 9 (the run has 6)"),
    (["train", "push", "--resume", "{run}", "--engine", "mjx"], "drop --engine mjx (the run has native)"),
    (["train", "push", "--engine", "warp"], "argument --engine: expected one of mjx, native, auto, got 'warp'"),
    (["train", "push", "--resume", "{run}", "--optimizer", "random"], "drop --optimizer random (the run has mobo)"),
    (["train", "push", "--optimizer", "sobol"], "argument --optimizer: expected one of mobo, random, optuna-nsga2, optuna-tpe, optuna-gp, botorch-qlognehvi, got 'sobol'"),
    (["train", "push", "--workers", "0"], "argument --workers: must be at least 1, got 0"),
    (["train", "push", "--workers", "100000"], "argument --workers: must be at most 256, got 100000"),
    (["experiment", "push", "--workers", "two"], "argument --workers: expected an integer, got 'two'"),
    (["train", "{broken}"], "bt_hz"),
    (["train", "push", "--goal", "(skiros:at skiros:Nothing-1 skiros:ObjectGoalPose-1)"], "unknown object 'nothing-1'"),
    (["evaluate", "{tmp}"], "is not a run directory"),
    (["evaluate", "{run}", "--per-config", "0"], "argument --per-config: must be at least 1"),
    (["select", "{run}", "--pick", "99"], "--pick 99: the front has rows"),
    (["select", "{run}", "--max-force", "-1"], "argument --max-force: must be a finite number >= 0"),
    (["select", "{run}", "--min-success", "2"], "--min-success is a rate between 0 and 1"),
    (["train", "push", "--optimizer-option", "model=single"], "--optimizer-option: acquisition setting model: expected one of"),
    (["train", "push", "--optimizer-option", "n_raw=4", "--optimizer-option", "n_restarts=5"],
     "--optimizer-option: acquisition setting n_restarts (5) exceeds n_raw (4)"),
)


# A few cases go through a real subprocess; the rest call the same entry point in-process
# (a subprocess costs seconds of imports on a loaded 2-core machine).
SUBPROCESS_CASES = {0, 1, 8}


@pytest.mark.parametrize("index, case, message", [(i, c, m) for i, (c, m) in enumerate(BAD_INPUT)])
def test_bad_input_is_one_message_and_exit_code_2(repeated_run, tmp_path, capsys, case, message, index):
    out, _ = repeated_run
    fill = {"tmp": tmp_path, "run": out / "seed-1", "broken": bad_scenario(tmp_path) if "{broken}" in case else ""}
    args = [arg.format(**fill) for arg in case]
    if index in SUBPROCESS_CASES:
        done = run_cli(*args, timeout=120)
        code, stderr = done.returncode, done.stderr
    else:
        code, stderr = invoke(capsys, *args)
    assert code == 2, stderr
    assert "Traceback" not in stderr
    assert message in stderr
    assert f"mjxskill.{case[0]}: error:" in stderr
