"""Static facts of the MJCF scenes and start postures, checked in native
MuJoCo against the published iiwa figures and the task geometry."""

from __future__ import annotations

import mjxskill  # noqa: F401
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from mjxskill.sim import load_scene, postures, scene_path
from mjxskill.sim.scene import ARM_JOINTS
from scenes import HOLE_CLEARANCE, HOLE_DEPTH, HOLE_TOP

JOINT_Z = [0.1575, 0.36, 0.5645, 0.78, 0.9645, 1.18, 1.261]
AXES = [[0, 0, 1], [0, 1, 0], [0, 0, 1], [0, -1, 0], [0, 0, 1], [0, 1, 0], [0, 0, 1]]
LIMITS_DEG = [170, 120, 170, 120, 170, 120, 175]
TORQUES = [320, 320, 176, 176, 110, 40, 40]
MASSES = [5.76, 6.35, 3.5, 3.5, 3.5, 1.8, 1.2]


@pytest.fixture(scope="module", params=["push", "peg", "peg_square"])
def scene(request):
    return request.param, load_scene(request.param)


def test_arm_kinematics_dynamics_and_actuators_match_the_iiwa14(scene):
    _, model = scene
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # qpos0 = arm straight up
    for i, name in enumerate(ARM_JOINTS):
        j = model.joint(name).id
        np.testing.assert_allclose(data.xanchor[j], [0, 0, JOINT_Z[i]], atol=1e-9)
        np.testing.assert_allclose(data.xaxis[j], AXES[i], atol=1e-9)
        np.testing.assert_allclose(np.degrees(model.jnt_range[j]), [-LIMITS_DEG[i], LIMITS_DEG[i]], atol=1e-3)
        assert model.body_mass[model.jnt_bodyid[j]] == pytest.approx(MASSES[i])
        act = model.actuator(name)
        assert act.trnid[0] == j
        np.testing.assert_allclose(act.ctrlrange, [-TORQUES[i], TORQUES[i]])
    np.testing.assert_allclose(data.body("flange").xpos, [0, 0, 1.306], atol=1e-9)
    np.testing.assert_allclose(data.site("tool").xpos, [0, 0, 1.356], atol=1e-9)  # 0.05 m tool
    assert model.body("iiwa_base").mass == pytest.approx(5.0)


def test_only_tool_and_objects_collide(scene):
    name, model = scene
    assert np.all(model.geom_contype == 0) and np.all(model.geom_conaffinity == 0)
    pair_geoms = {model.geom(int(g)).name for g in np.concatenate([model.pair_geom1, model.pair_geom2])}
    walls = {"tool_geom", "wall_px", "wall_nx", "wall_py", "wall_ny", "bottom"}
    expected = {"push": {"tool_geom", "object", "table", "fence", "stop"},
                "peg": walls | {f"ring_{k:02d}" for k in range(16)}, "peg_square": walls}[name]
    assert pair_geoms == expected
    # MJX accepts the scene (it raises for collision pairs it has no function for).
    mjx.put_model(model)


def test_push_object_and_tool_geometry():
    model = load_scene("push")
    obj = model.body("object")
    assert obj.mass == pytest.approx(2.5)
    mesh = model.mesh("prism")
    verts = model.mesh_vert[mesh.vertadr[0]:mesh.vertadr[0] + mesh.vertnum[0]]
    # MuJoCo stores meshes in their own principal frame; the geom's pose maps them back.
    geom = model.geom("object")
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, geom.quat)
    verts = verts @ rot.reshape(3, 3).T + geom.pos
    legs = sorted(np.ptp(verts[:, :2], axis=0))
    np.testing.assert_allclose(legs, [0.15, 0.30], atol=1e-6)  # legs along body x and y
    extent = verts.max(0) - verts.min(0)
    np.testing.assert_allclose(sorted(extent), [0.07, 0.15, 0.30], atol=1e-6)
    assert mesh.vertnum[0] == 6  # a prism: two triangles
    # uneven weight distribution: centre of mass away from the geometric centroid
    centroid_local = verts.mean(0)
    assert np.linalg.norm(obj.ipos - centroid_local) > 0.02
    np.testing.assert_allclose(model.geom("tool_geom").size, [0.035, 0.035, 0.025])
    goal = model.body("goal")
    assert goal.mocapid[0] >= 0
    assert np.linalg.norm(goal.pos[:2] - obj.pos[:2]) == pytest.approx(0.43, abs=0.005)
    yaw = 2 * np.arctan2(goal.quat[3], goal.quat[0])
    assert np.degrees(yaw) == pytest.approx(26.0, abs=0.1)
    friction = {model.geom(int(model.pair_geom2[i])).name: model.pair_friction[i, 0] for i in range(model.npair)}
    assert 0.2 <= min(friction.values()) and max(friction.values()) <= 0.25


def _prism_vertices(model, data):
    """World positions (6, 3) of the push prism's vertices."""
    geom = model.geom("object").id
    mesh = model.mesh("prism")
    verts = model.mesh_vert[mesh.vertadr[0]:mesh.vertadr[0] + mesh.vertnum[0]]
    return verts @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]


def _inside(model, data, name, points):
    """Signed distances (m) of points (N, 3) from a fixture plane, positive on the prism's side."""
    geom = model.geom(name).id
    normal = data.geom_xmat[geom].reshape(3, 3)[:, 2]
    return (np.asarray(points) - data.geom_xpos[geom]) @ normal


def test_the_goal_corner_holds_the_prism_at_the_goal_pose():
    model = load_scene("push")
    data = mujoco.MjData(model)
    goal = model.body("goal")
    # The prism at the goal pose touches the fence with its hypotenuse and the stop with its tip.
    data.qpos[7:10], data.qpos[10:14] = goal.pos, goal.quat
    mujoco.mj_kinematics(model, data)
    verts = _prism_vertices(model, data)
    fence, stop = _inside(model, data, "fence", verts), _inside(model, data, "stop", verts)
    assert np.sum(np.abs(fence) < 1e-6) == 4 and np.all(fence > -1e-6)  # hypotenuse face: 4 vertices
    assert np.sum(np.abs(stop) < 1e-6) == 2 and np.all(stop > -1e-6)  # the tip's edge
    # At the start, the prism and the tool of every start posture are well inside the corner.
    data.qpos[7:10], data.qpos[10:14] = model.body("object").pos, [1, 0, 0, 0]
    for q in np.concatenate([postures.PUSH_STARTS, postures.PUSH_EVAL_STARTS]):
        data.qpos[:7] = q
        mujoco.mj_kinematics(model, data)
        points = np.concatenate([_prism_vertices(model, data), [data.site("tool").xpos]])
        for plane in ("fence", "stop"):
            assert np.all(_inside(model, data, plane, points) > 0.1), plane


def test_round_peg_hole_clearance_and_depth():
    # the peg's 16 vertices on a 0.015 m circle, each facing a slab whose inner face is tangent
    # to the 0.0165 m hole: the gap is the clearance there and larger everywhere else
    model = load_scene("peg")
    assert model.body("box").mocapid[0] >= 0
    peg = model.geom("tool_geom")
    assert peg.type == mujoco.mjtGeom.mjGEOM_MESH
    verts = model.mesh_vert[model.mesh_vertadr[peg.dataid[0]]:][:model.mesh_vertnum[peg.dataid[0]]]
    np.testing.assert_allclose(np.hypot(verts[:, 0], verts[:, 1]), 0.015, rtol=2e-5)  # 7 digits in the MJCF
    np.testing.assert_allclose(np.ptp(verts[:, 2]), 0.05, rtol=1e-6)
    vertex_angles = np.sort(np.mod(np.arctan2(verts[:16, 1], verts[:16, 0]), 2 * np.pi))
    for k in range(16):
        slab = model.geom(f"ring_{k:02d}")
        normal_angle = np.arctan2(slab.pos[1], slab.pos[0]) % (2 * np.pi)
        assert normal_angle == pytest.approx(vertex_angles[k], abs=1e-5)  # float32 vertices
        assert np.hypot(*slab.pos[:2]) - slab.size[0] - 0.015 == pytest.approx(HOLE_CLEARANCE, abs=1e-7)
        assert slab.pos[2] + slab.size[2] == pytest.approx(HOLE_TOP)
    floor = model.geom("bottom").pos[2] + model.geom("bottom").size[2]
    assert HOLE_TOP - floor == pytest.approx(HOLE_DEPTH)
    np.testing.assert_allclose(model.pair_friction[:, 0], 0.3)


def test_square_peg_hole_clearance_and_depth():
    model = load_scene("peg_square")
    assert model.body("box").mocapid[0] >= 0
    peg_half = model.geom("tool_geom").size[0]
    inner = model.geom("wall_px").pos[0] - model.geom("wall_px").size[0]
    assert inner - peg_half == pytest.approx(HOLE_CLEARANCE)
    top = model.geom("wall_px").pos[2] + model.geom("wall_px").size[2]
    floor = model.geom("bottom").pos[2] + model.geom("bottom").size[2]
    assert top == pytest.approx(HOLE_TOP) and top - floor == pytest.approx(HOLE_DEPTH)
    assert HOLE_DEPTH >= 0.03
    np.testing.assert_allclose(model.pair_friction[:, 0], 0.3)


@pytest.mark.parametrize("group,count", [("PUSH_STARTS", 4), ("PUSH_EVAL_STARTS", 2),
                                         ("PEG_STARTS", 5), ("PEG_EVAL_STARTS", 10)])
def test_start_postures_hold_the_tool_down_above_the_table(group, count):
    model = load_scene("peg")
    qs = getattr(postures, group)
    assert qs.shape == (count, 7)
    data = mujoco.MjData(model)
    for q in qs:
        assert np.all(q > model.jnt_range[:7, 0]) and np.all(q < model.jnt_range[:7, 1])
        data.qpos[:7] = q
        mujoco.mj_kinematics(model, data)
        assert 0.05 <= data.site("tool").xpos[2] <= 0.15
        z_axis = data.site("tool").xmat.reshape(3, 3)[:, 2]
        assert np.degrees(np.arccos(-z_axis[2])) < 0.5
        assert 0.4 <= data.site("tool").xpos[0] <= 0.66 and abs(data.site("tool").xpos[1]) <= 0.25


def test_unknown_scene_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown scene 'pegs'"):
        scene_path("pegs")
