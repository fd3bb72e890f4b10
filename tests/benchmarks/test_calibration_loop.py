"""benchmarks/calibration_loop.py's pieces at a tiny size (the loop itself is two full training
runs): the true twin's YAML loads with the issue's values, its recordings read back, and a pick's
success in the true twin is counted over the same worlds for every pick."""

import os
import sys

import numpy as np
import pytest

from mjxskill.calibration.recording import read_recording
from mjxskill.calibration.twin import parameter_values
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
import calibration_loop as loop  # noqa: E402


@pytest.fixture(scope="module")
def true_yaml(tmp_path_factory):
    return loop.write_true_twin(tmp_path_factory.mktemp("loop"))


def test_the_true_twin_is_push_with_the_issues_changes(true_yaml):
    nominal, true = load_scenario("push"), load_scenario(true_yaml)
    name = "ObjectToBePushed-1"
    values, base = parameter_values(true), parameter_values(nominal)
    assert values[f"{name}.mass"] == pytest.approx(1.2 * base[f"{name}.mass"])
    assert values[f"{name}.friction"] == pytest.approx(1.5 * base[f"{name}.friction"])
    assert values[f"{name}.com_offset.x"] == pytest.approx(base[f"{name}.com_offset.x"] + 0.02)
    assert true.randomization.friction_range is None and true.scene == nominal.scene


def test_its_recordings_read_back_against_the_nominal_twin(true_yaml, tmp_path):
    paths = loop.record(true_yaml, tmp_path / "recordings", 1, seed=5)
    scn = load_scenario("push")
    rec = read_recording(paths[0], scn, plan_task(scn))
    assert rec.source.startswith("twin ") and rec.tool_force is not None and len(rec.time) == 1200


def test_picks_are_counted_in_the_same_worlds_of_the_true_twin(true_yaml):
    scn = load_scenario("push")
    task = plan_task(scn)
    operator = np.array([scn.manual_parameters["operator_b"].values[n] for n in task.parameter_names])
    result = loop.success_in_twin(true_yaml, {"a": operator, "b": operator}, per_config=1)
    assert result["a"] == result["b"] and result["a"]["worlds"] == 6
    assert 0.0 <= result["a"]["all"] <= 1.0
