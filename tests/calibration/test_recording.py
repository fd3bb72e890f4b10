"""The recording format's reader (mjxskill.calibration.recording): a good file reads back as
written; every bad one (wrong columns, NaN, another robot, too short, a parameter outside its
skill's bounds, ...) is one located RecordingError naming the file, the array and, for a value,
its sample and time; through the command, one ``error:`` line and exit code 2, nothing written.
No simulation: the recordings here are made of plausible arrays."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cli_helpers import error_line, invoke
from scenario_texts import shipped_text
from mjxskill.calibration.recording import FORMAT, read_recording, write_npz
from mjxskill.errors import RecordingError
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task

SCN = load_scenario("push")
TASK = plan_task(SCN)
SAMPLES = 600


def arrays(samples: int = SAMPLES) -> dict:
    """A recording of the push task as a robot would write it (a straight slide of the prism)."""
    t = np.arange(1, samples + 1) * 0.01
    start = np.array(SCN.robot.start_configs[0], float)
    obj = SCN.objects["ObjectToBePushed-1"]
    goal = SCN.objects["ObjectGoalPose-1"]
    pos = np.tile(obj.pose.position, (samples, 1))
    pos[:, 1] += np.clip(t - 3.0, 0, None) * 0.1
    operator = SCN.manual_parameters["operator_a"].values
    return {
        "format": FORMAT, "robot": SCN.robot.name, "time": t,
        "joint_position": np.tile(start, (samples, 1)), "object_position": pos,
        "object_quaternion": np.tile([1.0, 0.0, 0.0, 0.0], (samples, 1)),
        "parameter_names": np.array(TASK.parameter_names),
        "parameter_values": np.array([operator[n] for n in TASK.parameter_names]),
        "start_configuration": start.copy(),
        "start_object_names": np.array([obj.name, goal.name]),
        "start_positions": np.array([obj.pose.position, goal.pose.position]),
        "start_quaternions": np.array([obj.pose.quat, goal.pose.quat]),
        "tool_force": np.zeros(samples), "joint_torque": np.zeros((samples, 7)),
    }


def write(folder, values: dict, name: str = "ep00.npz"):
    path = folder / name
    path.write_bytes(write_npz(values))
    return path


def refused(path, *fragments) -> str:
    with pytest.raises(RecordingError) as caught:
        read_recording(path, SCN, TASK)
    message = str(caught.value)
    assert "\n" not in message and message.startswith(f"{path}: "), message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    return message


def test_a_good_recording_reads_back(tmp_path):
    values = arrays()
    values["parameter_names"] = values["parameter_names"][::-1]  # any order: read in the plan's
    values["parameter_values"] = values["parameter_values"][::-1]
    rec = read_recording(write(tmp_path, values), SCN, TASK)
    assert rec.robot == SCN.robot.name and rec.joint_position.shape == (SAMPLES, 7)
    operator = SCN.manual_parameters["operator_a"].values
    assert np.allclose(rec.parameters, [operator[n] for n in TASK.parameter_names])
    assert set(rec.start_poses) == {"ObjectToBePushed-1", "ObjectGoalPose-1"} and rec.period == pytest.approx(0.01)
    assert not rec.time.flags.writeable


CASES = {
    "wrong columns": (lambda v: v.update(joint_position=v["joint_position"][:, :6]), "joint_position", "6 joints"),
    "object position of 2 columns": (lambda v: v.update(object_position=v["object_position"][:, :2]),
                                     "object_position", "expected shape (T, 3)"),
    "another robot": (lambda v: v.update(robot="ur5-1"), "robot", "'ur5-1'"),
    "too short": (lambda v: [v.update({k: v[k][:20]}) for k in ("time", "joint_position", "object_position",
                                                                   "object_quaternion", "tool_force", "joint_torque")],
                  "time", "too short"),
    "parameter outside its bounds": (lambda v: v["parameter_values"].__setitem__(0, 0.5), "parameter_values",
                                     "outside the skill's bounds"),
    "a parameter of another skill": (lambda v: v.update(parameter_names=np.array(["PegInsertion.force"] * 4)),
                                     "parameter_names", "'PegInsertion.force' is not a learnable parameter"),
    "missing array": (lambda v: v.pop("object_quaternion"), "missing array 'object_quaternion'"),
    "unknown array": (lambda v: v.update(object_velocity=np.zeros(3)), "unknown array 'object_velocity'"),
    "other format": (lambda v: v.update(format="csv/2"), "format", "'csv/2'"),
    "times not increasing": (lambda v: v["time"].__setitem__(10, v["time"][9]), "time[10]", "must increase"),
    "samples too far apart": (lambda v: v.update(time=0.01 + (v["time"] - 0.01) * 10), "time", "at least 20 per second"),
    "degrees for radians": (lambda v: v["joint_position"].__setitem__((5, 3), -110.0), "joint_position[5, 3]", "degrees?"),
    "not a unit quaternion": (lambda v: v["object_quaternion"].__setitem__(7, [2.0, 0, 0, 0]), "object_quaternion[7]",
                              "unit quaternion"),
    "samples missing from one array": (lambda v: v.update(tool_force=v["tool_force"][:-5]), "tool_force", "595 samples"),
    "an object not of the scenario": (lambda v: v.update(start_object_names=np.array(["Box-9", "ObjectGoalPose-1"])),
                                      "start_object_names", "'Box-9'"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_each_bad_recording_is_one_located_error(tmp_path, case):
    change, *fragments = CASES[case]
    values = arrays()
    change(values)
    refused(write(tmp_path, values), *fragments)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(array=st.sampled_from(["time", "joint_position", "object_position", "object_quaternion", "tool_force",
                              "joint_torque", "parameter_values", "start_configuration", "start_positions"]),
       where=st.floats(0, 1), value=st.sampled_from([np.nan, np.inf, -np.inf]))
def test_a_value_that_is_not_finite_is_named_by_array_sample_and_time(tmp_path_factory, array, where, value):
    values = arrays()
    flat = values[array].reshape(-1)
    k = min(int(where * flat.size), flat.size - 1)
    flat[k] = value
    path = write(tmp_path_factory.mktemp("nan"), values)
    index = np.unravel_index(k, values[array].shape)
    at = f"{array}[{', '.join(map(str, index))}]"
    message = refused(path, at, "not a finite number")
    if values[array].shape[0] == SAMPLES and array != "time":
        assert f"t = {values['time'][index[0]]:.3f} s" in message


@pytest.mark.parametrize("content", [b"", b"not an archive", b"PK\x03\x04 broken zip"])
def test_a_file_that_is_no_archive_is_refused(tmp_path, content):
    path = tmp_path / "ep.npz"
    path.write_bytes(content)
    refused(path, "not a NumPy .npz archive")


def test_the_command_names_the_bad_recording_and_writes_nothing(tmp_path, capsys):
    folder = tmp_path / "recordings"
    folder.mkdir()
    write(folder, arrays(), "ep00.npz")
    bad = arrays()
    bad["object_position"][123, 1] = np.nan
    write(folder, bad, "ep01.npz")
    code, err = invoke(capsys, "calibrate", "push", "--recordings", folder, "--out", tmp_path / "out.yaml")
    if "mjxskill[calibrate]" in err:
        pytest.skip("the calibrate extra is not installed")
    error_line(code, err, "calibrate", "ep01.npz: object_position[123, 1]", "t = 1.240 s")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["recordings"]


@pytest.mark.parametrize("args, fragment", [
    (["--recordings", "{tmp}/none"], "not a folder"),
    (["--recordings", "{tmp}"], "no recording (.npz file)"),
    (["--recordings", "{tmp}", "--out", "{tmp}/out.txt"], "a scenario is a .yaml file"),
])
def test_the_command_refuses_bad_flags(tmp_path, capsys, args, fragment):
    args = [a.format(tmp=tmp_path) for a in args]
    if "--out" not in args:
        args += ["--out", str(tmp_path / "out.yaml")]
    code, err = invoke(capsys, "calibrate", "push", *args)
    if "mjxskill[calibrate]" in err:
        pytest.skip("the calibrate extra is not installed")
    error_line(code, err, "calibrate", fragment)


def test_a_scenario_without_a_calibration_section_is_refused(tmp_path, capsys):
    code, err = invoke(capsys, "calibrate", "peg", "--recordings", tmp_path, "--out", tmp_path / "out.yaml")
    if "mjxskill[calibrate]" in err:
        pytest.skip("the calibrate extra is not installed")
    error_line(code, err, "calibrate", "has no calibration section")


def test_bounds_that_do_not_hold_the_yamls_value_are_refused_before_any_recording_is_read(tmp_path, capsys):
    text = shipped_text("push").replace("    mass: 2.5\n", "    mass: 7.5\n", 1)
    path = tmp_path / "push.yaml"
    path.write_text(text)
    code, err = invoke(capsys, "calibrate", path, "--recordings", tmp_path / "none", "--out", tmp_path / "out.yaml")
    if "mjxskill[calibrate]" in err:
        pytest.skip("the calibrate extra is not installed")
    error_line(code, err, "calibrate", "calibration.parameters.ObjectToBePushed-1.mass (line",
               "do not hold the YAML's value 7.5 kg")


def test_without_the_extra_the_command_says_what_to_install(tmp_path, capsys, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "plotly" else real(name, *a))
    code, err = invoke(capsys, "calibrate", "push", "--recordings", tmp_path, "--out", tmp_path / "out.yaml")
    error_line(code, err, "calibrate", "plotly is not installed", "pip install 'mjxskill[calibrate]'")
