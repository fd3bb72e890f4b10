"""The world model against the MJCF scene it names (native MuJoCo, no JAX): every MJCF name
exists, poses agree, and the start postures hold the tool above the table pointing down."""


import numpy as np
import pytest

import mujoco

from mjxskill.scenario import load_scenario


@pytest.fixture(scope="module", params=["push", "peg", "peg_square", "slide"])
def scene(request):
    scn = load_scenario(request.param)
    return scn, mujoco.MjModel.from_xml_path(scn.scene)


def test_every_mjcf_name_exists(scene):
    scn, model = scene
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, scn.robot.tool_site) >= 0
    for obj in scn.objects.values():
        if obj.mjcf_body is not None:
            assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, obj.mjcf_body) >= 0, obj.name


def test_object_poses_agree_with_the_scene(scene):
    scn, model = scene
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    relations = {*scn.robot.relations, *(r for o in scn.objects.values() for r in o.relations)}
    for obj in scn.objects.values():
        held = f"(holding {scn.robot.pddl_name} {obj.pddl_name})" in relations
        if obj.mjcf_body is None or held:
            continue  # poses without a body, and tools that move with the flange
        body = data.body(obj.mjcf_body)
        np.testing.assert_allclose(body.xpos, obj.pose.position, atol=1e-3, err_msg=obj.name)
        np.testing.assert_allclose(np.abs(body.xquat @ obj.pose.quat), 1.0, atol=1e-4, err_msg=obj.name)


def test_start_postures_hold_the_tool_down_above_the_table(scene):
    scn, model = scene
    data = mujoco.MjData(model)
    site = data.site(scn.robot.tool_site)
    for q in np.concatenate([scn.robot.start_configs, scn.robot.eval_configs]):
        data.qpos[:7] = q
        mujoco.mj_kinematics(model, data)
        assert 0.05 <= site.xpos[2] <= 0.2, q
        assert site.xmat.reshape(3, 3)[:, 2] @ [0, 0, -1] > 0.99, q  # tool z along world -z


@pytest.mark.parametrize("task", ["push", "peg"])  # the tasks whose postures the sim package holds
def test_start_postures_are_the_sim_packages(task):
    from mjxskill.sim import postures
    scn = load_scenario(task)
    name = scn.name.upper()
    np.testing.assert_array_equal(scn.robot.start_configs, getattr(postures, f"{name}_STARTS"))
    np.testing.assert_array_equal(scn.robot.eval_configs, getattr(postures, f"{name}_EVAL_STARTS"))
