"""A resume with a scenario whose content differs from the run's copy:
``train other.yaml --resume R`` with the same task but a 250 kg object resumed silently and
mixed two physics in one run. It is refused naming the first difference (key path and both
values) and writes nothing; with ``--accept-scenario-change`` the change is recorded in
config.yaml, which names the new scenario, and the previous copy is kept."""

import time

import pytest

from cli_helpers import error_line, invoke, snapshot
from mjxskill.runs.run_dir import Run
from mjxskill.runs.run_task import first_difference, record_scenario_change, scenario_difference
from mjxskill.scenario import load_scenario
from scenario_texts import shipped_text
from push_runs import push_run

MASS = "    mass: 2.5\n"


def heavy_copy(tmp_path):
    text = shipped_text("push")
    assert text.count(MASS) == 1
    path = tmp_path / "other.yaml"
    path.write_text(text.replace(MASS, "    mass: 250\n"))
    return path


def test_first_difference_names_the_key_path_and_both_values():
    assert first_difference({"a": {"b": [1, 2.0]}}, {"a": {"b": [1.0, 2]}}) is None  # numbers by value
    assert first_difference({"a": {"b": [1, 2]}}, {"a": {"b": [1, 3]}}) == ("a.b[1]", 2, 3)
    assert first_difference({"a": 1}, {"a": 1, "c": 2}) == ("c", "(absent)", 2)
    assert first_difference({"a": [1]}, {"a": []}) == ("a[0]", 1, "(absent)")
    assert first_difference({"a": True}, {"a": 1}) == ("a", True, 1)  # true is no number


def test_a_copy_with_its_scene_named_from_elsewhere_is_the_same_scenario(tmp_path):
    run = push_run(tmp_path / "run")
    moved = tmp_path / "elsewhere" / "push.yaml"
    moved.parent.mkdir()
    moved.write_text(shipped_text("push"))  # the scene and library as absolute paths
    assert scenario_difference(run, load_scenario(moved)) is None
    assert scenario_difference(run, load_scenario("push")) is None


@pytest.mark.parametrize("command", ["train", "experiment"])
def test_a_resume_with_another_scenario_is_refused_naming_the_first_difference(tmp_path, capsys, command):
    if command == "train":
        folder = push_run(tmp_path / "run").path
    else:
        from mjxskill.experiment.directory import Experiment, Protocol

        folder = tmp_path / "exp"
        template = push_run(tmp_path / "template")
        Experiment(folder).create(template.config(), Protocol(per_config=1, random_sets=0, max_force=None,
                                                              max_force_source=None),
                                  load_scenario("push").source, {"plan.txt": "x"})
    other = heavy_copy(tmp_path)
    before = snapshot(folder)
    code, err = invoke(capsys, command, other, "--resume", folder)
    error_line(code, err, command, str(other), "objects.ObjectToBePushed-1.mass: 2.5 in the run, 250 in",
               "--accept-scenario-change")
    assert snapshot(folder) == before


def test_an_accepted_change_is_recorded_in_config_yaml_and_the_copy_kept(tmp_path):
    run = push_run(tmp_path / "run")
    other = heavy_copy(tmp_path)
    scn = load_scenario(other)
    old_copy = (run.path / "scenario.yaml").read_text()
    difference = scenario_difference(run, scn)
    record_scenario_change(run.path, str(other), scn, difference)
    config = Run(run.path).config()
    assert config.scenario == str(other.resolve())
    (change,) = config.scenario_changes
    assert change == {"scenario": str(other.resolve()), "evaluations": 0, "previous_copy": "scenario.yaml.orig-1",
                      "difference": difference.text()}
    assert (run.path / "scenario.yaml.orig-1").read_text() == old_copy
    assert (run.path / "scenario.yaml").read_text() == other.read_text()
    assert scenario_difference(Run(run.path), scn) is None  # the new scenario is the run's own now
    assert scenario_difference(Run(run.path), load_scenario("push")).where == "objects.ObjectToBePushed-1.mass"


def test_train_resumes_with_an_accepted_change(tmp_path, capsys):
    run = push_run(tmp_path / "run", engine="native")
    other = heavy_copy(tmp_path)
    started = time.monotonic()
    code = invoke(capsys, "train", other, "--resume", run.path, "--accept-scenario-change", "--workers", 1, "--quiet")[0]
    assert code == 0, capsys.readouterr()
    config = Run(run.path).config()
    assert config.scenario == str(other.resolve()) and len(config.scenario_changes) == 1
    assert len(Run(run.path).evaluations(config)) == config.budget
    print(f"trained in {time.monotonic() - started:.0f} s")


def test_a_run_read_for_its_task_after_its_scenario_changed_says_so(tmp_path):
    """evaluate, select, explore and the experiment's picks read a run's task with
    load_run_task: where the scenario file no longer holds what the run learned in (here the
    run's copy says 250 kg, the shipped file 2.5 kg), a Notice names the first difference, and
    the run's own unchanged copy gives none."""
    import warnings

    from mjxskill.errors import Notice
    from mjxskill.runs.run_task import load_run_task

    run = push_run(tmp_path / "run")
    with warnings.catch_warnings():
        warnings.simplefilter("error", Notice)
        load_run_task(run, run.config())  # the same scenario: no notice
    (run.path / "scenario.yaml").write_text(heavy_copy(tmp_path).read_text())
    with pytest.warns(Notice, match=r"objects\.ObjectToBePushed-1\.mass: 250 in the run, 2\.5 in .*push\.yaml"):
        load_run_task(run, run.config())

