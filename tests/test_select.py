"""select: choosing a Pareto point by constraint, the export document, offscreen rendering."""

from mjxskill.training.render import default_gl

default_gl()  # MUJOCO_GL=egl when headless; must precede the first import of mujoco

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from mjxskill.errors import CommandError  # noqa: E402
from mjxskill.training.run_dir import Evaluations  # noqa: E402
from mjxskill.training.selection import choose, export_document  # noqa: E402
from test_run_dir import make_config  # noqa: E402

FRONT = Evaluations(
    iteration=np.array([0, 1, 2, 3]),
    params=np.array([[0.1, 0.0], [0.2, 0.5], [0.3, -0.5], [0.4, 1.0]]),
    objectives=np.array([[5.0, -1.0], [7.0, -2.0], [7.5, -3.0], [9.0, -4.0]]),
    success_rate=np.array([0.2, 0.6, 0.6, 1.0]),
    max_force=np.array([2.0, 5.0, 8.0, 12.0]),
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
        with pytest.raises(CommandError, match="no Pareto solution meets --max-force 8, --min-success 0.7"):
            choose(FRONT, max_force, min_success)
    else:
        assert choose(FRONT, max_force, min_success) == expected


def test_export_names_every_parameter_with_its_unit(tmp_path):
    doc = export_document(make_config(), FRONT, 2, tmp_path)
    assert doc["parameters"] == {"S.x": {"value": 0.3, "unit": "m"}, "S.y": {"value": -0.5, "unit": "N"}}
    assert doc["objectives"] == {"reach": 7.5, "force": -3.0}
    assert doc["success_rate"] == 0.6 and doc["max_force_N"] == 8.0 and doc["pareto_index"] == 2


def test_frames_match_the_scene_or_explain_how_to_get_gl():
    """Offscreen frames of a native model at two poses (differ where the box moved); without a
    GL backend the error says how to get one."""
    import mujoco

    from mjxskill.training.render import RenderUnavailable, frames

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><light pos="0 0 3"/><geom type="plane" size="2 2 .1"/>'
        '<body pos="0.5 0 0.1"><freejoint/><geom type="box" size=".1 .1 .1" rgba="1 0 0 1"/></body></worldbody></mujoco>'
    )
    qpos = np.array([[0.5, 0, 0.1, 1, 0, 0, 0], [0.2, 0.3, 0.1, 1, 0, 0, 0]])
    try:
        images = frames(model, qpos, width=96, height=64)
    except RenderUnavailable as err:
        assert "MUJOCO_GL=egl" in str(err) and "--no-render" in str(err)
        pytest.skip(f"no OpenGL backend here: {err}")
    assert images.shape == (2, 64, 96, 3) and images.dtype == np.uint8
    red = lambda im: (im[..., 0] > 150) & (im[..., 1] < 80)  # noqa: E731
    assert red(images[0]).any() and red(images[1]).any()
    assert not np.array_equal(red(images[0]), red(images[1]))
