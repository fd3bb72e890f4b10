"""``train --optimizer optuna-*``: Optuna's samplers as runs like any other. The loop with a
closed-form objective (the shared warm-up, resuming to the same rows, NSGA-II's generations
against Optuna's own bookkeeping), the real command on a tiny push run (the files of a run, a
kill and resume), and the refusal without the extra."""

import shutil
import sys
from dataclasses import replace

import numpy as np
import pytest
import yaml

import optuna  # noqa: E402  (the test extra's)

from capabilities import require  # noqa: E402
from cli_helpers import error_line, invoke, run_cli  # noqa: E402
from mjxskill.runs.run_dir import EVALUATIONS, PARETO, Run  # noqa: E402
from mjxskill.training import optuna_search  # noqa: E402
from mjxskill.training.extras import missing_extra  # noqa: E402
from mjxskill.training.loop import train  # noqa: E402
from toy_runs import CONFIG, Recorder, new_run, toy_objective  # noqa: E402

# batches of 4, 2 (the warm-up), then 4, 4, 4 from the sampler
TOY = replace(CONFIG, budget=18)
TOY_SIZES = [4, 2, 4, 4, 4]


def _toy(optimizer):
    return replace(TOY, optimizer=optimizer)


@pytest.fixture(scope="module")
def random_rows(tmp_path_factory):
    """Random search's rows of the same seed: its warm-up is the Bayesian optimizer's
    (tests/training/test_random_search.py), and its model-free draws cost no GP fit here."""
    config = _toy("random")
    return train(new_run(tmp_path_factory.mktemp("random"), "random", config), config, toy_objective)


@pytest.mark.parametrize("optimizer", ["optuna-nsga2", "optuna-tpe", "optuna-gp"])
def test_the_sampler_proposes_after_the_shared_warm_up_and_resumes_to_the_same_rows(tmp_path, optimizer, random_rows):
    if optimizer == "optuna-gp":
        require("torch")  # not in the test extra: a multi-GB download for one sampler
    config = _toy(optimizer)
    full = new_run(tmp_path, "full", config)
    recorder = Recorder()
    ev = train(full, config, recorder)
    assert [len(x) for _, x in recorder.calls] == TOY_SIZES
    # the warm-up is the Bayesian optimizer's own; the sampler's rows are its own and in the bounds
    np.testing.assert_array_equal(ev.params[:6], random_rows.params[:6])
    assert not np.allclose(ev.params[6:10], random_rows.params[6:10])
    lo, hi = np.asarray(config.bounds)
    assert np.all((ev.params >= lo) & (ev.params <= hi))
    assert len({tuple(row) for row in ev.params[6:]}) > 1
    cut = new_run(tmp_path, "cut", config)
    with pytest.raises(KeyboardInterrupt):  # a Ctrl-C during the fourth batch, the sampler's second
        train(cut, config, Recorder(stop_after=3))
    second = Recorder()
    train(cut, config, second)
    assert [it for it, _ in second.calls] == [3, 4]
    assert (cut.path / EVALUATIONS).read_text() == (full.path / EVALUATIONS).read_text()


def test_the_sampler_is_seeded_by_the_seed_and_the_rows():
    rng = np.random.default_rng(0)
    lo, hi = np.asarray(TOY.bounds)
    x = lo + rng.random((10, len(lo))) * (hi - lo)
    y = toy_objective(x, 0).objectives
    config = _toy("optuna-tpe")
    first = optuna_search.ask(config, x, y, 4)
    np.testing.assert_array_equal(first, optuna_search.ask(config, x, y, 4))  # a function of its inputs
    assert not np.allclose(first, optuna_search.ask(replace(config, seed=config.seed + 1), x, y, 4))
    assert optuna_search.sampler_seed(3, 10) != optuna_search.sampler_seed(3, 11)


def test_nsga2_generations_are_the_ones_optuna_gives_a_study_asked_in_batches():
    """Optuna's own NSGA-II, asked and told batch by batch like the loop does, stamps each trial
    with its generation; the rebuilt study must give every row the same (failed rows included)."""
    config = replace(TOY, optimizer="optuna-nsga2", budget=40, batch_size=5, n_init=7)
    sizes = [5, 2, 5, 5, 5, 5, 5, 5, 3]
    sampler = optuna.samplers.NSGAIISampler(population_size=config.n_init, seed=1)
    study = optuna.create_study(directions=["maximize", "maximize"], sampler=sampler)
    space = {"a": optuna.distributions.FloatDistribution(0, 1), "b": optuna.distributions.FloatDistribution(0, 1)}
    objectives = []
    for b, size in enumerate(sizes):
        trials = [study.ask(space) for _ in range(size)]
        for i, trial in enumerate(trials):
            values = [trial.params["a"], -trial.params["b"]]
            if (b, i) in {(2, 0), (3, 1), (3, 2)}:  # a diverged world: a failed trial
                study.tell(trial, state=optuna.trial.TrialState.FAIL)
                values = [np.nan, np.nan]
            else:
                study.tell(trial, values)
            objectives.append(values)
    expected = [t.system_attrs[sampler._get_generation_key()] for t in study.trials]
    assert max(expected) >= 3  # several generations, one of them short of complete trials
    assert optuna_search._generations(config, np.array(objectives)) == expected


def test_missing_extra_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "torch", None)  # an import of a module set to None fails
    assert missing_extra("optuna-gp") == "needs PyTorch, which is not installed: pip install 'mjxskill[optuna-gp]'"
    monkeypatch.setitem(sys.modules, "optuna", None)
    assert "needs Optuna and PyTorch, which are not installed" in missing_extra("optuna-gp")
    assert missing_extra("optuna-tpe") == "needs Optuna, which is not installed: pip install 'mjxskill[optuna]'"
    assert missing_extra("mobo") is None and missing_extra("random") is None


# The real command: tiny episodes, one world; the files of a run, not the physics.
TINY = ["--budget", "12", "--batch-size", "6", "--init", "6", "--worlds", "1", "--episode-seconds", "0.2",
        "--engine", "native", "--quiet", "--seed", "3", "--protocol", "paper"]


@pytest.fixture(scope="module")
def cli_runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("optuna")
    runs = {}
    for optimizer in ("optuna-nsga2", "optuna-tpe"):
        done = run_cli("train", "push", *TINY, "--optimizer", optimizer, "--out", out / optimizer)
        assert done.returncode == 0, done.stderr[-3000:]
        runs[optimizer] = out / optimizer
    return runs


@pytest.mark.parametrize("optimizer", ["optuna-nsga2", "optuna-tpe"])
def test_train_writes_a_run_with_its_front(cli_runs, optimizer):
    path = cli_runs[optimizer]
    assert yaml.safe_load((path / "config.yaml").read_text())["optimizer"] == optimizer
    run = Run(path)
    config = run.config()
    ev = run.evaluations(config)
    assert list(ev.iteration) == [0] * 6 + [1] * 6 and np.all(np.isfinite(ev.objectives))
    # pareto.csv: exactly the non-dominated rows (larger is better), by brute force
    y = ev.objectives
    dominated = [any(np.all(y[j] >= y[i]) and np.any(y[j] > y[i]) for j in range(len(y))) for i in range(len(y))]
    front = run.pareto()
    assert len(front) >= 1
    assert {tuple(r) for r in front.objectives} == {tuple(r) for r in y[~np.array(dominated)]}
    for name in ("pareto.png", "hypervolume.png", PARETO):
        assert (path / name).is_file()


def test_an_optuna_run_cut_after_its_warm_up_resumes_to_the_same_results(cli_runs, tmp_path):
    """The run as a kill leaves it: the warm-up batch on disk and two rows of the sampler's batch
    (set aside on resume); the resumed run rebuilds the study from the file alone."""
    reference = cli_runs["optuna-nsga2"]
    cut = tmp_path / "cut"
    shutil.copytree(reference, cut)
    for name in ("pareto.csv", "pareto.png", "hypervolume.png", "optimizer_state.npz"):
        (cut / name).unlink()
    lines = (reference / EVALUATIONS).read_text().splitlines(keepends=True)
    (cut / EVALUATIONS).write_text("".join(lines[:9]))  # the header, 6 warm-up rows, 2 of the next batch
    resumed = run_cli("train", "push", "--resume", cut, "--quiet")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert "2 rows" in resumed.stderr and "set aside" in resumed.stderr
    assert (cut / EVALUATIONS).read_text() == (reference / EVALUATIONS).read_text()
    assert (cut / PARETO).read_text() == (reference / PARETO).read_text()


def test_without_the_extra_train_says_how_to_install_it(monkeypatch, capsys, tmp_path, cli_runs):
    monkeypatch.setitem(sys.modules, "optuna", None)
    out = tmp_path / "never"
    code, err = invoke(capsys, "train", "push", *TINY, "--optimizer", "optuna-tpe", "--out", out)
    error_line(code, err, "train", "--optimizer optuna-tpe needs Optuna", "pip install 'mjxskill[optuna]'")
    assert not out.exists()  # refused before the run directory is made
    code, err = invoke(capsys, "train", "push", "--resume", cli_runs["optuna-tpe"], "--quiet")
    error_line(code, err, "train", "trains with the optimizer optuna-tpe, which needs Optuna",
               "pip install 'mjxskill[optuna]'")
