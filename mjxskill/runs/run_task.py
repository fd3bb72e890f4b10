"""The scenario and the plan a run directory was trained on, checked against the scenario file
as it is now (a run is only continued, evaluated or selected from with its own task).

A resume also compares the scenario file it is given with the run's copy (``scenario.yaml``),
as data: ``train other.yaml --resume R`` with the same task but a 250 kg object resumed
silently and mixed two physics in one run. ``scenario_difference`` names the first difference;
the command refuses unless told to accept it, and then ``record_scenario_change`` records it in
every ``config.yaml`` of the run (which also names the new scenario from then on) and makes the
new text the run's copy, keeping the previous one as ``scenario.yaml.orig-<n>``."""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from mjxskill.errors import Notice, RunError, UserError, quote
from mjxskill.runs.atomic_write import write_text
from mjxskill.runs.run_dir import CONFIG, EVALUATIONS, SCENARIO_COPY, Run, RunConfig
from mjxskill.runs.training_protocol import objective_names
from mjxskill.scenario import load_scenario, scenario_path
from mjxskill.scenario.fields import compose_text, read_text
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
        mismatch.append(f"task {quote(config.task)}, not {quote(scn.name)}")
    elif tuple(task.parameter_names) != config.parameter_names:
        mismatch.append(f"parameters {list(config.parameter_names)}, not {list(task.parameter_names)}")
    elif objective_names(scn.objective_names, config.protocol) != config.objective_names:
        mismatch.append(f"objectives {list(config.objective_names)}, not "
                        f"{list(objective_names(scn.objective_names, config.protocol))}")
    elif not np.array_equal(np.asarray(task.bounds, np.float64), np.asarray(config.bounds, np.float64)):
        mismatch.append(f"parameter bounds {[list(b) for b in config.bounds]}, not the scenario's current "
                        f"{np.asarray(task.bounds).tolist()} (the scenario file changed since)")
    if mismatch:
        raise RunError(f"{where} is a run of {mismatch[0]}: use it with its own task")


def load_run_task(run: Run, config: RunConfig, scenario: str | None = None):
    """``(Scenario, PlannedTask)`` a run was trained on (its scenario, or ``scenario`` given
    for it), checked to still match the run. Where the run's own scenario file has changed
    since it trained (its copy, ``scenario.yaml``, holds other data), a ``Notice`` names the
    first difference: what the caller rolls out runs on the file as it is now, another twin
    than the one the run learned in (a resume, given ``scenario``, compares and decides itself)."""
    scn = load_scenario(config.scenario if scenario is None else scenario)
    if scn.name != config.task:
        raise RunError(f"{run.path} is a run of task {quote(config.task)}, not {quote(scn.name)}")
    task = plan_task(scn, config.goal)
    check_same_task(scn, task, config, run.path)
    if scenario is None and os.path.lexists(run.path / SCENARIO_COPY):
        difference = scenario_difference(run, scn, config)
        if difference is not None:
            warnings.warn(f"{run.path}: its scenario changed since the run learned ({difference.text()}); "
                          "these episodes are rolled out with the file as it is now", Notice, stacklevel=2)
    return scn, task


ABSENT = "(absent)"


@dataclass(frozen=True)
class Difference:
    """The first place where the run's copy of its scenario and the file given differ."""

    copy: Path  # the run's scenario.yaml
    source: str  # the file the resume was given
    where: str  # key path, e.g. objects.ObjectToBePushed-1.mass
    run_value: object
    file_value: object

    def text(self) -> str:
        return f"{self.where or '<top level>'}: {_show(self.run_value)} in the run, {_show(self.file_value)} in {self.source}"


def _show(value) -> str:
    text = ABSENT if value is ABSENT else repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _data(text: str, source: str):
    root = compose_text(text, source, RunError)  # bounded and safe, as every YAML read
    return yaml.constructor.SafeConstructor().construct_document(root.node)


def first_difference(a, b, where: str = ""):
    """(key path, a's value, b's value) of the first difference between two YAML documents,
    in a's order (keys only b has after a's), or None; numbers compare by value."""
    if isinstance(a, dict) and isinstance(b, dict):
        for key in [*a, *(k for k in b if k not in a)]:
            path = f"{where}.{key}" if where else str(key)
            if key not in a or key not in b:
                return path, a.get(key, ABSENT), b.get(key, ABSENT)
            found = first_difference(a[key], b[key], path)
            if found:
                return found
        return None
    if isinstance(a, list) and isinstance(b, list):
        for i in range(max(len(a), len(b))):
            path = f"{where}[{i}]"
            if i >= len(a) or i >= len(b):
                return path, a[i] if i < len(a) else ABSENT, b[i] if i < len(b) else ABSENT
            found = first_difference(a[i], b[i], path)
            if found:
                return found
        return None
    number = (int, float)
    same = (a == b and not isinstance(a, bool) and not isinstance(b, bool) and isinstance(a, number) and isinstance(b, number)) \
        or (type(a) is type(b) and a == b)
    return None if same else (where, a, b)


PATH_KEYS = ("scene", "skill_library")  # relative to the scenario file: compared as the files they name


def _resolved(data, base: Path):
    """``data`` with its file names made absolute against ``base`` (a copy moved elsewhere, with
    its scene named from there, names the same scene)."""
    if not isinstance(data, dict):
        return data
    out = dict(data)
    for key in PATH_KEYS:
        value = out.get(key)
        if isinstance(value, str):
            out[key] = str((base / value).resolve())
        elif isinstance(value, list):
            out[key] = [str((base / v).resolve()) if isinstance(v, str) else v for v in value]
    return out


def scenario_difference(run: Run, scn, config: RunConfig | None = None) -> Difference | None:
    """How the scenario file ``scn`` was loaded from differs from the run's copy (None: the same
    data; the copy's file names are taken from where the run's scenario was, ``config.scenario``);
    RunError when the copy is missing or damaged."""
    copy = run.path / SCENARIO_COPY
    if not os.path.lexists(copy):
        raise RunError(f"{copy} is missing: the run's copy of its scenario, which a resume compares with the scenario "
                       "it is given; restore it")
    config = run.config() if config is None else config
    try:
        base = scenario_path(config.scenario).parent
    except UserError:  # a shipped name no longer shipped
        base = copy.parent
    kept = _resolved(_data(read_text(copy, RunError, "run's copy of its scenario"), str(copy)), base)
    given = _resolved(_data(read_text(Path(scn.source)), str(scn.source)), Path(scn.source).parent)
    found = first_difference(kept, given)
    return None if found is None else Difference(copy, str(scn.source), *found)


def record_scenario_change(root: Path, scenario: str, scn, difference: Difference) -> None:
    """Every run under ``root`` (``root`` itself, its sub-runs, an experiment's runs) continues
    with ``scn``: its config.yaml records the change and names ``scenario`` (a name or a path,
    made absolute), then the scenario's text becomes its copy, the previous one kept."""
    named = str(Path(scenario).resolve()) if Path(scenario).is_file() else scenario
    text = read_text(Path(scn.source))
    plans = []  # everything read and checked before the first write
    for folder, dirs, files in os.walk(root):  # does not follow links
        dirs.sort()
        if CONFIG not in files:
            continue
        run = Run(folder)
        config = run.config()
        n = 1
        while os.path.lexists(run.path / f"{SCENARIO_COPY}.orig-{n}"):
            n += 1
        change: dict[str, str | int] = {"scenario": named, "difference": difference.text(),
                                        "previous_copy": f"{SCENARIO_COPY}.orig-{n}"}
        if config.repeats == 1 and os.path.lexists(run.path / EVALUATIONS):
            change["evaluations"] = len(run.evaluations(config))
        kept = read_text(run.path / SCENARIO_COPY, RunError, "run's copy of its scenario")
        plans.append((run, replace(config, scenario=named, scenario_changes=(*config.scenario_changes, change)), kept))
    for run, config, kept in plans:  # a kill in between: the next resume finds the difference again
        write_text(run.path / config.scenario_changes[-1]["previous_copy"], kept)
        write_text(run.path / CONFIG, config.to_yaml())
        write_text(run.path / SCENARIO_COPY, text)
