"""A run's parameter prior: from the scenario's parameter_priors by default, from an earlier
run's Pareto front with --prior-from (refused when the parameters differ), stored in config.yaml
and checked when read, and the same on resume. Closed-form objectives, no physics."""

from pathlib import Path

import numpy as np
import pytest

from cli_helpers import error_line, invoke
from mjxskill.errors import ResumeConflict, RunError
from mjxskill.gp import Prior
from mjxskill.runs.evaluations_csv import Evaluations
from mjxskill.training.front import pareto_mask_of
from mjxskill.training.loop import train
from mjxskill.training.configure import new_run_config, resumed_run_config
from mjxskill.training.priors import PRIOR_FROM_STD_FRACTION, prior_from_run
from mjxskill.runs.run_config import RunConfig, optimizer_config
from mjxskill.runs.run_dir import EVALUATIONS, Run
from scenario_texts import shipped_text
from toy_runs import Recorder, make_config, new_run, rows

TOY_PRIOR = {"source": "test", "mean": [[0.8, -0.5]], "std": [[0.05, 0.1]], "weights": [1.0]}


def run_with_front(tmp_path, name, config, seed=0):
    """A run directory holding 12 evaluated rows and their Pareto front."""
    src = tmp_path / f"{name}.src.yaml"
    src.write_text("name: toy\n")
    run = Run(tmp_path / name)
    run.create(config, str(src), {})
    ev = rows([0] * 12, p=len(config.parameter_names), seed=seed)
    lo, hi = np.asarray(config.bounds)
    u = ev.params[:, 0]
    # A trade-off: the even rows are on the front, most odd ones dominated.
    objectives = np.stack([u, 1 - u - 0.5 * (np.arange(12) % 2)], axis=1)
    ev = Evaluations(ev.iteration, lo + ev.params * (hi - lo), objectives, *tuple(ev)[3:])

    run.write_evaluations(config, ev)
    run.write_pareto(config, ev, pareto_mask_of(ev))
    return run


def test_prior_from_a_run_has_one_component_per_pareto_solution(tmp_path):
    config = make_config()
    run = run_with_front(tmp_path, "earlier", config)
    front = run.pareto(config)
    prior = prior_from_run(run.path, config.parameter_names, config.bounds)
    order = np.argsort(-front.objectives[:, 0], kind="stable")
    np.testing.assert_array_equal(prior["mean"], front.params[order])
    np.testing.assert_allclose(prior["std"], np.broadcast_to([0.1 * 1.0, 0.1 * 2.0], front.params.shape))
    assert PRIOR_FROM_STD_FRACTION == 0.1
    k = len(front)
    assert k >= 6 and prior["weights"] == [1 / k] * k and f"{k} Pareto solutions" in prior["source"]


def test_prior_from_a_run_with_other_parameters_names_what_differs(tmp_path):
    run = run_with_front(tmp_path, "other", make_config(parameter_names=("S.x", "S.z")))
    with pytest.raises(RunError, match=r"learnable parameters differ from this task's \(it lacks S.y; it has S.z besides"):
        prior_from_run(run.path, ("S.x", "S.y"), make_config().bounds)


def test_the_prior_is_stored_in_config_yaml_and_checked_when_read(tmp_path):
    config = make_config(prior=TOY_PRIOR)
    text = config.to_yaml()
    assert RunConfig.from_yaml(text, "config.yaml") == config
    assert optimizer_config(config).prior == Prior(mean=[0.8, -0.5], std=[0.05, 0.1])
    assert RunConfig.from_yaml(make_config().to_yaml(), "config.yaml").prior is None
    old = make_config().to_yaml().replace("prior: null\n", "")  # a run written before priors
    assert "prior" not in old and RunConfig.from_yaml(old, "config.yaml").prior is None
    bad = text.replace("- -0.5", "- -1.5")
    assert bad != text
    line = bad[: bad.index("prior:")].count("\n") + 1
    with pytest.raises(RunError, match=rf"config.yaml: prior \(line {line}\): Prior.mean: component 0, dimension 1 = -1.5 "
                                       r"lies outside the bounds \[-1, 1\] \(parameters: S.x, S.y\)"):
        RunConfig.from_yaml(bad, "config.yaml")


def test_a_run_with_a_prior_resumes_with_it(tmp_path):
    # Warm-up only (6 rows in batches of 4 and 2): the prior's draws, no model to compile.
    config = make_config(budget=6, prior=TOY_PRIOR)
    whole = new_run(tmp_path, "whole", config)
    train(whole, config, Recorder())
    cut = new_run(tmp_path, "cut", config)
    with pytest.raises(KeyboardInterrupt):
        train(cut, config, Recorder(stop_after=1))
    resumed = Run(cut.path).config()
    assert resumed.prior == TOY_PRIOR
    train(cut, resumed, Recorder())
    assert (cut.path / EVALUATIONS).read_text() == (whole.path / EVALUATIONS).read_text()
    plain = new_run(tmp_path, "plain", make_config(budget=6))
    train(plain, make_config(budget=6), Recorder())
    with_prior, without = whole.evaluations().params, plain.evaluations().params
    np.testing.assert_array_equal(with_prior[1::2], without[1::2])  # the uniform half is a plain run's
    assert np.all(np.abs(with_prior[0::2] - [0.8, -0.5]) < [0.3, 0.6])  # the prior's half lies near its mean


def test_resume_refuses_a_prior_other_than_the_runs_own(tmp_path, capsys):
    config = make_config()
    earlier = run_with_front(tmp_path, "earlier", config, seed=1)
    run = run_with_front(tmp_path, "run", make_config(prior=prior_from_run(earlier.path, config.parameter_names,
                                                                              config.bounds)))
    other = run_with_front(tmp_path, "other", config, seed=2)
    assert resumed_run_config(run.path, prior_from=earlier.path).prior == run.config().prior
    with pytest.raises(ResumeConflict, match="with the prior it started with") as refused:
        resumed_run_config(run.path, prior_from=other.path)
    assert refused.value.conflicts == (("prior", other.path, run.config().prior),)
    code, stderr = invoke(capsys, "train", "push", "--resume", run.path, "--prior-from", other.path)
    error_line(code, stderr, "train", "drop --prior-from")


def test_prior_from_a_run_of_other_parameters_is_exit_code_2(tmp_path, capsys):
    toy = run_with_front(tmp_path, "toy", make_config())
    code, stderr = invoke(capsys, "train", "push", "--prior-from", toy.path, "--out", tmp_path / "new")
    error_line(code, stderr, "train", f"--prior-from {toy.path}: its learnable parameters differ", "it lacks Push.offset_x_start")
    assert not (tmp_path / "new").exists()


PRIORS = ("parameter_priors:\n  Push.offset_x_start: {mean: -0.03, std: 0.05}\n"
          "  Push.offset_y_goal: {mean: -0.1, std: 0.04}\nmanual_parameters:\n")


def test_the_scenarios_prior_is_the_default_and_prior_from_overrides_it(tmp_path):
    from mjxskill.runs.run_task import scenario_and_task

    path = tmp_path / "push.yaml"
    path.write_text(shipped_text("push").replace("manual_parameters:\n", PRIORS, 1))
    scn, task = scenario_and_task(str(path), None)
    config = new_run_config(scn, task, str(path), {"budget": 60, "protocol": "paper"})
    lo, hi = np.asarray(task.bounds)
    assert task.parameter_names[0] == "Push.offset_x_start" and task.parameter_names[3] == "Push.offset_y_goal"
    assert config.prior["mean"] == [[-0.03, 0.0, 0.0, -0.1]]
    assert config.prior["std"] == [[0.05, 10 * 0.6, 10 * 0.6, 0.04]]  # the others flat: 10 times their range
    assert "parameter_priors: Push.offset_x_start, Push.offset_y_goal" in config.prior["source"]
    earlier = run_with_front(tmp_path, "earlier", make_config(parameter_names=task.parameter_names,
                                                              parameter_units=task.parameter_units,
                                                              bounds=(tuple(map(float, lo)), tuple(map(float, hi)))))
    over = new_run_config(scn, task, str(path), {"budget": 60, "protocol": "paper"}, prior_from=earlier.path)
    assert over.prior["mean"] == prior_from_run(earlier.path, task.parameter_names, task.bounds)["mean"]
    assert over.prior["source"].endswith("overrides the scenario's parameter_priors")
    plain, plain_task = scenario_and_task("push", None)
    assert new_run_config(plain, plain_task, "push").prior is None  # shipped: none


def test_the_header_says_which_prior_the_run_uses():
    from mjxskill.training.priors import describe_prior

    assert describe_prior(None) == "prior: none (uniform warm-up, plain acquisition)"
    two = {**TOY_PRIOR, "source": "run runs/a (2 Pareto solutions, std 10% of each range); overrides the scenario's "
                                  "parameter_priors", "mean": [[0.1, 0.0], [0.2, 0.0]], "std": [[0.1, 0.2]] * 2,
           "weights": [0.5, 0.5]}
    assert describe_prior(two) == ("prior: from the run runs/a (2 Pareto solutions, std 10% of each range); overrides "
                                   "the scenario's parameter_priors, 2 components")
