"""The real commands under the robust protocol (the default) on a tiny push task (0.2 s
episodes, 2 worlds): train rolls sets out again and races its front for the pick, a run killed
with SIGKILL resumes to the same rows and the same race, select names the race's winner, and
the experiment races and confirms every repetition's pick and reports the episodes it spent."""

import json

import numpy as np
import pytest

from cli_helpers import QUICK_GP, kill_once_written, run_cli
from mjxskill.evaluation import racing
from mjxskill.runs.run_dir import EVALUATIONS, PARETO, Run
from mjxskill.runs.training_protocol import SUCCESS_OBJECTIVE

GP = [a for option in QUICK_GP for a in ("--optimizer-option", option)]
# 12 x 2 x 1.15 = 27 episodes: 9 evaluations (batches of 3, a warm-up of 3) and a race of 9
TINY = ["--budget", "12", "--batch-size", "3", "--init", "3", "--worlds", "2", "--episode-seconds", "0.2", "--quiet", *GP]


@pytest.fixture(scope="module")
def robust_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("robust") / "push"
    done = run_cli("train", "push", *TINY, "--seed", "1", "--out", out)
    assert done.returncode == 0, done.stderr[-3000:]
    return out, done.stdout


def test_train_rolls_sets_out_again_and_races_its_front(robust_run):
    out, stdout = robust_run
    assert f"objectives (larger is better): success, applied_force, {SUCCESS_OBJECTIVE}" in stdout
    assert "robust protocol: 9 evaluations" in stdout and "a race of the front in 9 episodes" in stdout
    run = Run(out)
    config = run.config()
    assert config.protocol == "robust" and config.training_rows == 9
    ev = run.evaluations(config)
    assert ev.pooled and len(ev) == 9 and int(np.sum(ev.replaces >= 0)) == 2  # one per batch after the warm-up
    race = json.loads((out / racing.FILE).read_text())
    assert race["winner"] in race["contenders"] and race["winner_worlds"] == 4  # 1 world from each known configuration
    assert f"picked: Pareto row {race['winner']}" in stdout and f"--pick {race['winner']}" in stdout
    front = run.pareto(config)
    np.testing.assert_array_equal(race["winner_params"], front.params[race["winner"]])


def test_select_names_the_race_winner(robust_run):
    out, _ = robust_run
    race = json.loads((out / racing.FILE).read_text())
    done = run_cli("select", out)
    assert done.returncode == 0, done.stderr
    assert f"race winner (the run's pick): row {race['winner']}, success {race['winner_successes']}/4" in done.stdout


def test_a_robust_run_killed_while_it_trains_resumes_to_the_same_rows_and_race(robust_run, tmp_path):
    out, _ = robust_run
    cut = tmp_path / "cut"
    # two batches on disk: the second rolled a set out again
    assert kill_once_written("train", ["push", *TINY, "--seed", "1", "--out", cut], cut / EVALUATIONS, 7)
    resumed = run_cli("train", "push", "--resume", cut, "--quiet")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    for name in (EVALUATIONS, PARETO, racing.FILE):
        assert (cut / name).read_text() == (out / name).read_text(), name


@pytest.fixture(scope="module")
def robust_experiment(tmp_path_factory):
    out = tmp_path_factory.mktemp("robust-experiment") / "push-exp"
    done = run_cli("experiment", "push", "--repeats", "2", *TINY, "--per-config", "1", "--random", "1",
                   "--confirm-per-config", "2", "--out", out)
    assert done.returncode == 0, done.stderr[-3000:]
    return out, done.stdout


def test_the_experiment_races_and_confirms_every_pick(robust_experiment):
    out, stdout = robust_experiment
    assert "picks made by racing the front in fresh worlds (the robust protocol)" in stdout
    assert "repetition 2 of 2 (seed 1): confirmation of the pick in 2 worlds per start configuration" in stdout
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == {"repetitions_done": 2, "repetitions": 2}
    for seed in (0, 1):
        run = out / "optimizer" / f"seed-{seed}"
        race = json.loads((run / racing.FILE).read_text())
        picked = next(p for p in report["picked"] if p["seed"] == seed)
        assert picked["pareto_row"] == race["winner"]
        confirmation = json.loads((run / "evaluation" / "confirmation.json").read_text())
        assert confirmation["candidates"]["names"][0] == "picked"
        np.testing.assert_array_equal(confirmation["candidates"]["params"][0], race["winner_params"])
        assert not (run / "evaluation" / "validation.json").exists()
        assert not (out / "random_search" / f"seed-{seed}" / racing.FILE).exists()  # the baseline is not raced
    episodes = report["episodes"]
    assert [e["training"] + e["replication"] for e in episodes] == [18, 18]
    assert all(e["total"] <= 27 for e in episodes)
    assert set(report["confirmation"]["pooled"]) == {"picked", "operator_a", "operator_b", "operator_c"}
    md = (out / "report.md").read_text()
    for heading in ("## Confirmation: the pick and the operators' sets in many worlds", "## Episodes spent"):
        assert heading in md
    times = json.loads((out / "state.json").read_text())["times"]
    assert all({"race_seconds", "confirm_seconds"} <= set(times[f"optimizer/seed-{s}"]) for s in (0, 1))


def test_the_robust_experiment_refuses_validation_flags(robust_experiment):
    out, _ = robust_experiment
    done = run_cli("experiment", "push", "--resume", out, "--validation-per-config", "3")
    assert done.returncode == 2 and "picks by racing its front (the robust protocol), not by validation" in done.stderr
