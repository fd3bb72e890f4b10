"""The scenario and the plan a run directory was trained on, checked against the scenario file
as it is now (a run is only continued, evaluated or selected from with its own task)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mjxskill.errors import RunError
from mjxskill.runs.run_dir import Run, RunConfig
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task


def scenario_and_task(scenario: str, goal: str | None = None):
    """``(Scenario, PlannedTask)`` of ``scenario`` (a name or a YAML path) for ``goal``
    (default: the scenario's)."""
    scn = load_scenario(scenario)
    return scn, plan_task(scn, goal)


def check_same_task(scn, task, config: RunConfig, where: Path) -> None:
    """Raises RunError when the scenario and plan differ from what the run at ``where`` trained."""
    mismatch = []
    if scn.name != config.task:
        mismatch.append(f"task {config.task!r}, not {scn.name!r}")
    elif tuple(task.parameter_names) != config.parameter_names:
        mismatch.append(f"parameters {list(config.parameter_names)}, not {list(task.parameter_names)}")
    elif tuple(scn.objective_names) != config.objective_names:
        mismatch.append(f"objectives {list(config.objective_names)}, not {list(scn.objective_names)}")
    elif not np.array_equal(np.asarray(task.bounds, np.float64), np.asarray(config.bounds, np.float64)):
        mismatch.append(f"parameter bounds {[list(b) for b in config.bounds]}, not the scenario's current "
                        f"{np.asarray(task.bounds).tolist()} (the scenario file changed since)")
    if mismatch:
        raise RunError(f"{where} is a run of {mismatch[0]}: use it with its own task")


def load_run_task(run: Run, config: RunConfig, scenario: str | None = None):
    """``(Scenario, PlannedTask)`` a run was trained on (its scenario, or ``scenario`` given
    for it), checked to still match the run."""
    scn = load_scenario(config.scenario if scenario is None else scenario)
    if scn.name != config.task:
        raise RunError(f"{run.path} is a run of task {config.task!r}, not {scn.name!r}")
    task = plan_task(scn, config.goal)
    check_same_task(scn, task, config, run.path)
    return scn, task
