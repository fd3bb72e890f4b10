"""select: choosing a Pareto point by constraint, the export document, offscreen rendering."""

from mjxskill.evaluation.render import default_gl

default_gl()  # MUJOCO_GL=egl when headless; must precede the first import of mujoco

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from mjxskill.errors import RunError  # noqa: E402
from mjxskill.runs.run_dir import Evaluations  # noqa: E402
from mjxskill.evaluation.selection import choose, export_document  # noqa: E402
from capabilities import no_render  # noqa: E402
from toy_runs import make_config  # noqa: E402

FRONT = Evaluations(
    iteration=np.array([0, 1, 2, 3]),
    params=np.array([[0.1, 0.0], [0.2, 0.5], [0.3, -0.5], [0.4, 1.0]]),
    objectives=np.array([[5.0, -1.0], [7.0, -2.0], [7.5, -3.0], [9.0, -4.0]]),
    success_rate=np.array([0.2, 0.6, 0.6, 1.0]),
    peak_contact_force=np.array([2.0, 5.0, 8.0, 12.0]),
    mean_contact_force=np.array([0.5, 1.0, 2.0, 3.0]),
    peak_commanded_force=np.full(4, 7.0),
)


@pytest.mark.parametrize(
    "max_force, min_success, expected",
    [
        (None, None, 3),  # most successful overall
        (10.0, None, 2),  # 0.6 twice under 10 N: the better first objective wins
        (5.0, None, 1),
        (4.9, None, 0),
        (None, 0.5, 3),
        (8.0, 0.7, None),  # nothing meets both
    ],
)
def test_choose_by_constraint(max_force, min_success, expected):
    if expected is None:
        with pytest.raises(RunError, match="no Pareto solution meets --max-force 8, --min-success 0.7"):
            choose(FRONT, max_force, min_success)
    else:
        assert choose(FRONT, max_force, min_success) == expected


# Rows 1 and 3 validated: row 3's training 100 % fell to 40 % in fresh worlds, row 1 held 90 %.
VALIDATED = np.array([np.nan, 0.9, np.nan, 0.4])


@pytest.mark.parametrize(
    "max_force, min_success, expected",
    [
        (None, None, 1),  # a validated row first, by its validation success
        (10.0, None, 1),  # row 2 (unvalidated, training 60 %) within 10 N as well: row 1 is validated
        (4.9, None, 0),  # no validated row within the limit: training success decides, as without
        (None, 0.95, None),  # row 3's 100 % is training; validated at 40 % it falls short
        (None, 0.5, 1),
    ],
)
def test_a_validated_solution_goes_first_by_its_validation_success(max_force, min_success, expected):
    if expected is None:
        with pytest.raises(RunError, match="no Pareto solution meets --min-success 0.95"):
            choose(FRONT, max_force, min_success, VALIDATED)
    else:
        assert choose(FRONT, max_force, min_success, VALIDATED) == expected
    if max_force is None and min_success is None:
        assert choose(FRONT, validated=np.full(4, np.nan)) == choose(FRONT) == 3  # none validated: as before


def test_between_equal_validations_the_faster_goes_first_as_in_the_experiments_pick():
    validated = np.array([np.nan, 0.8, 0.8, 0.8])
    # rows 1-3 equally validated; row 3 the best in training, row 2 the fastest in validation
    assert choose(FRONT, validated=validated) == 3  # no times: training success decides
    assert choose(FRONT, validated=validated, validated_seconds=np.array([np.nan, 9.0, 6.5, 8.0])) == 2
    assert choose(FRONT, 10.0, None, validated, np.array([np.nan, 6.0, 7.0, 1.0])) == 1  # row 3 above 10 N
    # a time unknown counts as slower than any known one
    assert choose(FRONT, validated=validated, validated_seconds=np.array([np.nan, np.nan, 9.0, np.nan])) == 2
    # a higher validation success still beats a faster one
    assert choose(FRONT, validated=np.array([np.nan, 0.9, 0.8, 0.8]),
                  validated_seconds=np.array([np.nan, 11.0, 2.0, 2.0])) == 1


def test_select_names_the_best_unvalidated_row_beside_a_validated_pick():
    from mjxskill.evaluation.selection import best_unvalidated

    assert best_unvalidated(FRONT, None, None, VALIDATED) == 2  # rows 0 and 2 unvalidated: 60 % beats 20 %
    assert best_unvalidated(FRONT, 4.9, None, VALIDATED) == 0
    assert best_unvalidated(FRONT, None, 0.7, VALIDATED) is None
    assert best_unvalidated(FRONT, None, None, np.ones(4)) is None


def test_among_validated_rows_the_validation_decides_not_the_training():
    # rows 1-3 validated in the reverse order of their training success (0.6, 0.6, 1.0)
    validated = np.array([np.nan, 0.8, 0.7, 0.5])
    assert choose(FRONT, None, None, validated) == 1
    assert choose(FRONT, 10.0, None, validated) == 1  # row 3 is beyond 10 N anyway
    assert choose(FRONT, None, None, np.array([np.nan, 0.7, 0.7, 0.5])) == 2  # a tie: the first objective (7.5 > 7)


def test_export_names_every_parameter_with_its_unit(tmp_path):
    doc = export_document(make_config(), FRONT, 2, tmp_path)
    assert doc["parameters"] == {"S.x": {"value": 0.3, "unit": "m"}, "S.y": {"value": -0.5, "unit": "N"}}
    assert doc["objectives"] == {"reach": 7.5, "force": -3.0}
    assert doc["success_rate"] == 0.6 and doc["pareto_index"] == 2
    assert (doc["peak_contact_force_N"], doc["mean_contact_force_N"], doc["peak_commanded_force_N"]) == (8.0, 2.0, 7.0)
    assert "validation_success_rate" not in doc  # not validated: nothing claimed
    validated = export_document(make_config(), FRONT, 2, tmp_path, (0.9, 20))
    assert validated["validation_success_rate"] == 0.9 and validated["validated_in"].startswith("20 fresh worlds")


def frames_or_skip(*args, **kwargs):
    """``frames``, or a skip naming why (no OpenGL backend here); where rendering must work (CI
    sets MJXSKILL_REQUIRE_RENDER=1 after installing Mesa's EGL: .ci/run) a failure."""
    from mjxskill.evaluation.render import RenderUnavailable, frames

    try:
        return frames(*args, **kwargs)
    except RenderUnavailable as err:
        assert "MUJOCO_GL=egl" in str(err) and "--no-render" in str(err)
        no_render(str(err))


def test_frames_match_the_scene_or_explain_how_to_get_gl():
    """Offscreen frames of a native model at two poses (differ where the box moved); without a
    GL backend the error says how to get one."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><light pos="0 0 3"/><geom type="plane" size="2 2 .1"/>'
        '<body pos="0.5 0 0.1"><freejoint/><geom type="box" size=".1 .1 .1" rgba="1 0 0 1"/></body></worldbody></mujoco>'
    )
    qpos = np.array([[0.5, 0, 0.1, 1, 0, 0, 0], [0.2, 0.3, 0.1, 1, 0, 0, 0]])
    images = frames_or_skip(model, qpos, width=96, height=64)
    assert images.shape == (2, 64, 96, 3) and images.dtype == np.uint8
    red = lambda im: (im[..., 0] > 150) & (im[..., 1] < 80)  # noqa: E731
    assert red(images[0]).any() and red(images[1]).any()
    assert not np.array_equal(red(images[0]), red(images[1]))


def test_frames_larger_than_the_models_framebuffer_are_drawn_and_the_model_is_left_as_it_was():
    """A 1280 x 720 frame of a model whose offscreen framebuffer is MuJoCo's default 640 x 480:
    drawn (the framebuffer follows the frame), not refused as if no OpenGL backend existed."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><light pos="0 0 3"/><geom type="plane" size="2 2 .1"/>'
        '<body pos="0.5 0 0.1"><geom type="box" size=".1 .1 .1" rgba="1 0 0 1"/></body></worldbody></mujoco>'
    )
    assert (model.vis.global_.offwidth, model.vis.global_.offheight) == (640, 480)
    images = frames_or_skip(model, np.zeros((1, 0)), width=1280, height=720)
    assert images.shape == (1, 720, 1280, 3) and ((images[0, ..., 0] > 150) & (images[0, ..., 1] < 80)).any()
    assert (model.vis.global_.offwidth, model.vis.global_.offheight) == (640, 480)


def test_a_force_limit_on_a_run_without_measured_forces_is_refused():
    # a run written before contact forces were measured: its commanded force is no measure of
    # what the tool did, so --max-force says so instead of choosing by it
    old = Evaluations(*FRONT[:4], np.full(4, np.nan), np.full(4, np.nan), FRONT.peak_commanded_force)
    with pytest.raises(RunError, match="written before contact forces were measured"):
        choose(old, 5.0)
    assert choose(old, None, 0.5) == 3


def test_a_rendered_episode_shows_the_worlds_randomized_poses(tmp_path):
    """render_episode (as select and the explorer call it) draws each world as it was: the prism
    where the world started it, the goal corner where the world put it. Reference: the same
    frame drawn from a model whose bodies sit at those poses."""
    import jax
    import mujoco

    from mjxskill import load_scenario, plan_task
    from mjxskill.engine.native import NativeRollout
    from mjxskill.evaluation.render import render_episode

    scn = load_scenario("push")
    engine = NativeRollout(scn, plan_task(scn), worlds=1, episode_seconds=0.2)
    world = jax.tree.map(lambda x: np.asarray(x)[0], engine.worlds_per_config(jax.random.key(0), 1))
    slots = engine.setup.bindings.slot_of
    moved = world.object_pos.copy()
    moved[slots["ObjectToBePushed-1"], :2] += (-0.08, 0.05)
    moved[slots["ObjectGoalPose-1"], :2] += (0.10, -0.06)
    world = world._replace(object_pos=moved)
    _, record = engine.trace(engine.task.defaults, world)
    goal = engine.mj_model.body("goal").mocapid[0]
    np.testing.assert_allclose(record.mocap_pos[0, goal], moved[slots["ObjectGoalPose-1"]], atol=1e-6)
    images = frames_or_skip(engine.mj_model, record.qpos[:1], 160, 120, mocap_pos=record.mocap_pos[:1],
                            mocap_quat=record.mocap_quat[:1])
    reference_model = engine.mj_model.__copy__()
    reference_model.body_pos[engine.mj_model.body("goal").id] = moved[slots["ObjectGoalPose-1"]]
    reference = frames_or_skip(reference_model, record.qpos[:1], 160, 120)
    nominal = frames_or_skip(engine.mj_model, record.qpos[:1], 160, 120)  # the goal at its nominal pose
    # the same picture (a grey level here and there: the world's float32 pose against the model's)
    assert np.abs(images[0].astype(int) - reference[0].astype(int)).max() <= 2
    assert np.abs(images[0].astype(int) - nominal[0].astype(int)).sum() > 1000  # the corner is elsewhere
    paths = render_episode(engine, engine.task.defaults, world, tmp_path / "frames", "png", 160, 120)
    assert len(paths) == engine.setup.ticks and all(p.stat().st_size > 0 for p in paths)
    first = plt_read(paths[0])
    np.testing.assert_allclose(first[..., :3], images[0] / 255.0, atol=1.5 / 255)


def plt_read(path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.imread(path)


# -- nothing the user has is replaced -------------------------------------------------------------
def _select(capsys, run_path, *args):
    from cli_helpers import invoke

    return invoke(capsys, "select", run_path, "--no-render", *args)


def test_select_again_with_the_same_pick_is_harmless(tmp_path, capsys):
    from explore_runs import make_push_run

    run = make_push_run(tmp_path / "push-0")
    assert _select(capsys, run.path, "--pick", 1)[0] == 0
    first = {p.name: p.read_bytes() for p in (run.path / "selected-1").iterdir()}
    assert _select(capsys, run.path, "--pick", 1)[0] == 0
    assert {p.name: p.read_bytes() for p in (run.path / "selected-1").iterdir()} == first


@pytest.mark.parametrize("name", ["parameters.yaml", "parameters.json"])
def test_select_keeps_a_parameter_file_edited_by_hand(tmp_path, capsys, name):
    from cli_helpers import error_line
    from explore_runs import make_push_run

    run = make_push_run(tmp_path / "push-0")
    assert _select(capsys, run.path, "--pick", 1)[0] == 0
    edited = run.path / "selected-1" / name
    edited.write_text(edited.read_text().replace("Push.offset_x_start", "Push.offset_x_start_tuned"))
    before = {p.name: p.read_bytes() for p in (run.path / "selected-1").iterdir()}
    code, err = _select(capsys, run.path, "--pick", 1)
    error_line(code, err, "select", str(edited), "is kept", "--out FOLDER")
    assert {p.name: p.read_bytes() for p in (run.path / "selected-1").iterdir()} == before


def test_select_out_into_a_users_folder_keeps_its_files(tmp_path, capsys):
    from cli_helpers import error_line
    from explore_runs import make_push_run

    run = make_push_run(tmp_path / "push-0")
    mine = tmp_path / "my-settings"
    mine.mkdir()
    (mine / "parameters.json").write_text('{"mine": true}\n')
    outside = tmp_path / "outside.yaml"
    outside.write_text("a file of the user's\n")
    code, err = _select(capsys, run.path, "--pick", 0, "--out", mine)
    error_line(code, err, "select", str(mine / "parameters.json"))
    assert sorted(p.name for p in mine.iterdir()) == ["parameters.json"]
    assert (mine / "parameters.json").read_text() == '{"mine": true}\n'
    linked = run.path / "selected-0"
    linked.mkdir()
    (linked / "parameters.yaml").symlink_to(outside)  # a link out of the run: never written through
    code, err = _select(capsys, run.path, "--pick", 0)
    error_line(code, err, "select", str(linked / "parameters.yaml"))
    assert outside.read_text() == "a file of the user's\n" and (linked / "parameters.yaml").is_symlink()


def test_the_same_pick_exported_through_two_spellings_of_the_runs_path_is_the_same_export(tmp_path, capsys, monkeypatch):
    """``select runs/push-0`` and ``select ./runs/push-0/`` (and the absolute path) write the
    same document: the second is harmless, not refused as other content."""
    from explore_runs import make_push_run

    run = make_push_run(tmp_path / "push-0")
    monkeypatch.chdir(tmp_path)
    for spelling in ("push-0", "./push-0/", str(run.path)):
        code, err = _select(capsys, spelling, "--pick", 1)
        assert code == 0, (spelling, err)
