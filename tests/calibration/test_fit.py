"""The calibration (mjxskill.calibration, python -m mjxskill.calibrate) on small synthetic cases:
the sysid parameters write what the scenario loader writes, a fit recovers a known friction from
two recordings of a twin that differs in it alone (push.yaml's calibration cut to the friction:
one parameter, seconds per fit), the command writes a calibrated scenario that loads, and the
calibrated YAML keeps the source's text but the values it changes."""

import numpy as np
import pytest
import yaml

from capabilities import missing
from cli_helpers import invoke
from scenario_texts import shipped_text
from mjxskill.calibration import missing_extra
from mjxskill.calibration.record import record_episodes, true_twin
from mjxskill.calibration.recording import read_recording, write_npz
from mjxskill.calibration.scenario_yaml import scenario_text
from mjxskill.calibration.twin import parameter_values, sysid_parameters, with_values
from mjxskill.scenario import load_scenario
from mjxskill.sim.model import build_model, scenario_spec
from mjxskill.task import plan_task

SCN = load_scenario("push")
TASK = plan_task(SCN)
TRUE = true_twin(SCN)
TRUTH = parameter_values(TRUE)


def needs_sysid():
    problem = missing_extra()
    if problem is not None:
        missing("MJXSKILL_REQUIRE_EXTRAS", problem)


CUT = ("    ObjectToBePushed-1.mass: [1.0, 6.0]\n", "    ObjectToBePushed-1.com_offset.x: [-0.07, 0.03]\n",
       "    ObjectToBePushed-1.com_offset.y: [-0.01, 0.09]\n")


@pytest.fixture(scope="module")
def friction_only(tmp_path_factory):
    """push.yaml with only the friction to fit, and two pushes of its twin whose friction is
    1.5 times the YAML's (the scenario's sensor noise) in a folder: (yaml path, folder)."""
    text = shipped_text("push")
    for line in CUT:
        assert text.count(line) == 1, line
        text = text.replace(line, "")
    folder = tmp_path_factory.mktemp("friction")
    path = folder / "push-friction.yaml"
    path.write_text(text)
    scn = load_scenario(path)
    true = true_twin(scn, {"friction": 1.5})
    recordings = folder / "recordings"
    recordings.mkdir()
    for k, arrays in enumerate(record_episodes(true, plan_task(true), 2, seed=3)):
        (recordings / f"ep{k:02d}.npz").write_bytes(write_npz(arrays))
    return path, recordings


def test_the_true_twin_differs_as_the_issue_says():
    nominal = parameter_values(SCN)
    name = "ObjectToBePushed-1"
    assert TRUTH[f"{name}.mass"] == pytest.approx(1.2 * nominal[f"{name}.mass"])
    assert TRUTH[f"{name}.friction"] == pytest.approx(1.5 * nominal[f"{name}.friction"])
    assert TRUTH[f"{name}.com_offset.x"] - nominal[f"{name}.com_offset.x"] == pytest.approx(0.02)
    assert TRUE.randomization.friction_range is None


def test_the_fitted_values_are_written_as_the_loader_writes_them():
    needs_sysid()
    from mujoco import sysid

    spec = scenario_spec(SCN)
    params = sysid_parameters(SCN, spec)
    params.update_from_vector(np.array([TRUTH[p.key] for p in SCN.calibration.parameters]))
    fitted = sysid.apply_param_modifiers(params, spec)
    loaded = build_model(with_values(SCN, TRUTH))
    body = loaded.body("object").id
    assert fitted.body_mass[body] == pytest.approx(loaded.body_mass[body])
    assert np.allclose(fitted.body_ipos[body], loaded.body_ipos[body], atol=1e-12)
    assert np.allclose(np.sort(fitted.body_inertia[body]), np.sort(loaded.body_inertia[body]), rtol=1e-9)
    assert np.allclose(fitted.pair_friction, loaded.pair_friction) and np.allclose(fitted.geom_friction, loaded.geom_friction)
    assert not np.allclose(loaded.pair_friction, build_model(SCN).pair_friction)  # the values did change something


def test_the_calibrated_yaml_keeps_the_text_and_loads(tmp_path):
    out = tmp_path / "sub" / "push-calibrated.yaml"
    out.parent.mkdir()
    block = ("calibrated:\n  values:\n    ObjectToBePushed-1.mass: {value: 3.0, low: 2.9, high: 3.1, nominal: 2.5}\n"
             "  confidence: 0.95\n  sources: [\"ep00.npz sha256:00\"]\n")
    text = scenario_text(SCN, TRUTH, out, friction_range=(0.28, 0.32), calibrated=block)
    out.write_text(text)
    scn = load_scenario(out)
    assert parameter_values(scn) == pytest.approx(TRUTH)
    assert scn.randomization.friction_range == (0.28, 0.32) and scn.scene == SCN.scene
    assert scn.calibrated.values["ObjectToBePushed-1.mass"] == (3.0, 2.9, 3.1)
    assert "# uneven weight distribution" in text  # the source's comments stay
    again = scenario_text(scn, TRUTH, out, calibrated=block)  # calibrated again: one calibrated section
    assert again.count("calibrated:") == 1


def test_a_fit_recovers_a_known_friction_from_two_recordings(friction_only):
    needs_sysid()
    from mjxskill.calibration.fit import calibrate

    path, recordings = friction_only
    scn = load_scenario(path)
    recs = [read_recording(p, scn, TASK) for p in sorted(recordings.glob("*.npz"))]
    fit = calibrate(scn, TASK, recs, max_evaluations=6)
    (friction,) = scn.calibration.parameters
    true = 1.5 * friction.nominal
    assert abs(fit.values[0] - true) < 0.05 * true, (fit.values, fit.log)
    assert fit.cost[1] < 0.2 * fit.cost[0]
    assert fit.toolbox_half_width[0] > 0 and fit.half_width[0] > 0


def test_the_command_writes_a_calibrated_scenario_and_its_report(friction_only, tmp_path, capsys):
    needs_sysid()
    path, recordings = friction_only
    out = tmp_path / "push-calibrated.yaml"
    code, err = invoke(capsys, "calibrate", path, "--recordings", recordings, "--out", out, "--max-evaluations", "2")
    assert code == 0, err
    scn = load_scenario(out)
    assert set(scn.calibrated.values) == {"ObjectToBePushed-1.friction"}
    value, low, high = scn.calibrated.values["ObjectToBePushed-1.friction"]
    assert scn.objects["ObjectToBePushed-1"].friction == pytest.approx(value, rel=1e-5)
    assert scn.randomization.friction_range == pytest.approx((low, high), rel=1e-5)  # the worlds' friction: the fit's
    assert len(scn.calibrated.sources) == 2 and all("sha256:" in s for s in scn.calibrated.sources)
    command = yaml.safe_load(out.read_text())["calibrated"]["command"]  # the command parsed, not the test runner's
    assert command.startswith("python -m mjxskill.calibrate ") and command.endswith("--max-evaluations 2")
    report = tmp_path / "push-calibrated.report"
    assert sorted(p.name for p in report.iterdir()) == ["report.html", "report.md", "trajectories.png"]
    assert "| ObjectToBePushed-1.friction |" in (report / "report.md").read_text()
    code, err = invoke(capsys, "calibrate", path, "--recordings", recordings, "--out", out, "--max-evaluations", "2")
    assert code == 2 and "--replace" in err  # what is there is kept, refused before any fitting
