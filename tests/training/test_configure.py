"""A run's configuration from plain values (mjxskill.training.configure), without argparse: the
values checked as config.yaml's, and what is refused raised as data (the setting, its value,
whether it was given), which the command line words with its flags (tests/cli/test_train.py,
tests/cli/test_bad_input.py)."""

from pathlib import Path

import pytest

from mjxskill.errors import PlanError, ResumeConflict, RunError, SettingError
from mjxskill.runs.run_config import RunConfig
from mjxskill.runs.run_task import scenario_and_task
from mjxskill.training.configure import new_run_config, resumed_run_config, stored_scenario
from toy_runs import make_config, make_run


@pytest.fixture(scope="module")
def push():
    return scenario_and_task("push", None)


def test_settings_over_the_scenarios_defaults(push):
    scn, task = push
    config = new_run_config(scn, task, "push", {"budget": "12", "n_init": 6, "seed": None, "engine": "native"},
                            {"n_raw": "64"})
    assert (config.budget, config.n_init, config.seed, config.engine) == (12, 6, scn.optimizer.seed, "native")
    assert config.optimizer_options == {"n_raw": 64}  # typed by gp, as --optimizer-option types it
    assert config.scenario == "push" and config.parameter_names == tuple(task.parameter_names)
    assert config.engine_reason == "as asked"
    auto = new_run_config(scn, task, "push")
    assert auto.engine in ("mjx", "native") and auto.engine_reason.startswith("auto: ")  # resolved once, and why
    # why is the header's, not the run's: config.yaml does not keep it, and a run read back equals its own
    assert "engine_reason" not in auto.to_yaml() and RunConfig.from_yaml(auto.to_yaml(), "run/config.yaml") == auto


def test_a_value_refused_says_which_setting_and_whether_it_was_given(push):
    scn, task = push
    with pytest.raises(SettingError, match="^n_init 10 exceeds the budget of 6 evaluations$") as given:
        new_run_config(scn, task, "push", {"budget": 6, "n_init": 10, "protocol": "paper"})
    assert (given.value.name, given.value.value, given.value.given) == ("n_init", 10, True)
    assert isinstance(given.value, RunError)
    with pytest.raises(SettingError, match=r"^n_init 6 exceeds the 5 evaluations the robust protocol trains with of "
                                           r"the budget of 6 \(the race has the rest\)$"):
        new_run_config(scn, task, "push", {"budget": 6, "n_init": 6})
    with pytest.raises(SettingError, match=r"\(the scenario's default\) exceeds the budget of 3") as default:
        new_run_config(scn, task, "push", {"budget": 3, "protocol": "paper"})
    assert (default.value.name, default.value.given) == ("n_init", False)
    with pytest.raises(SettingError, match="^budget: must be at least 1, got 0$"):
        new_run_config(scn, task, "push", {"budget": 0})
    with pytest.raises(ValueError, match="unknown run settings budgett"):
        new_run_config(scn, task, "push", {"budgett": 5})


def test_optimizer_options_refused_together(push):
    scn, task = push
    with pytest.raises(SettingError, match=r"optimizer_options: acquisition setting n_restarts \(5\) exceeds n_raw \(4\)") as err:
        new_run_config(scn, task, "push", optimizer_options={"n_raw": 4, "n_restarts": 5})
    assert (err.value.name, err.value.given) == ("optimizer_options", True)
    assert err.value.problem == "acquisition setting n_restarts (5) exceeds n_raw (4)"
    with pytest.raises(SettingError, match="unknown acquisition setting 'n_rwa'"):
        new_run_config(scn, task, "push", optimizer_options={"n_rwa": 3})


def test_a_plan_without_parameters_is_a_plan_error(push):
    scn, task = push
    from dataclasses import replace

    with pytest.raises(PlanError, match="leaves no parameter to learn"):
        new_run_config(scn, replace(task, parameters=()), "push")


def test_the_stored_scenario_is_a_name_or_an_absolute_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert stored_scenario("push") == "push"
    assert stored_scenario("cell.yaml") == str(tmp_path / "cell.yaml")
    assert stored_scenario("scenarios/push") == str(tmp_path / "scenarios" / "push")


def test_resume_refuses_values_that_are_not_the_runs_own(tmp_path):
    run = make_run(tmp_path, make_config(optimizer_options={"n_raw": 64}))
    assert resumed_run_config(run.path, {"budget": 10, "seed": None}, {"n_raw": 64}) == run.config()
    with pytest.raises(ResumeConflict, match="own optimizer options") as options:
        resumed_run_config(run.path, {"budget": 9}, {"n_raw": 32})
    assert options.value.conflicts == (("optimizer_options", {"n_raw": 32}, {"n_raw": 64}),)
    with pytest.raises(ResumeConflict, match="budget 9 given, the run has 10, seed 3 given, the run has 0") as settings:
        resumed_run_config(run.path, {"seed": 3, "budget": 9})
    assert settings.value.conflicts == (("budget", 9, 10), ("seed", 3, 0))  # in the order of the settings
    assert Path(settings.value.run) == run.path
