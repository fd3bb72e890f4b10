"""Closed-loop behaviour of scenes + controller + motion generator under MJX. Two compiled
rollouts in all (one per scene), each batching every case into one vmapped call; the assertions are physical facts
checked against native MuJoCo or closed-form targets."""

from __future__ import annotations

import mjxskill  # noqa: F401  (XLA flags before jax runs)
import jax
import mujoco
import numpy as np
import pytest

from sim_rollouts import (  # noqa: E402
    load_scene, make_scripted_rollout, make_task, native_tool_poses, put_worlds, tool_target_posture)

from mjxskill.sim import postures  # noqa: E402
from scenes import HOLE_TOP  # noqa: E402

ALL_STARTS = np.vstack([postures.PUSH_STARTS, postures.PUSH_EVAL_STARTS, postures.PEG_STARTS,
                        postures.PEG_EVAL_STARTS])
N_TRACK = len(ALL_STARTS)
TRACK_SECONDS = 4.0
HOLE_XY = np.array([0.55, 0.0])
PEG_STIFFNESS = [500.0, 500.0, 0.0, 50.0, 50.0, 50.0]  # SkiREIL's peg insertion
PUSH_STIFFNESS = [700.0, 700.0, 700.0, 50.0, 50.0, 50.0]  # SkiREIL's push


def _mul(a, b):
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, a, b)
    return out


@pytest.fixture(scope="module")
def peg_scene_run():
    """Free-space tracking from every start posture (box moved 5 m away) plus two insertion
    worlds (peg 5 mm above the hole, aligned / offset by 3 mm, 5 N down, zero z stiffness):
    one vmapped 2000-step rollout in the square peg scene (MJX's fastest peg geometry)."""
    model = load_scene("peg_square")
    rng = np.random.default_rng(0)
    pos0, quat0 = native_tool_poses(model, ALL_STARTS)
    # Goals 0.3 m away, upward and sideways, turned +-20 degrees about the world z.
    dirs = np.column_stack([rng.uniform(-0.4, 0.4, N_TRACK), rng.uniform(-0.4, 0.4, N_TRACK),
                            np.ones(N_TRACK)])
    goal_pos = pos0 + 0.3 * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    yaw = np.radians(np.where(np.arange(N_TRACK) % 2 == 0, 20.0, -20.0))
    goal_quat = np.array([_mul([np.cos(a / 2), 0, 0, np.sin(a / 2)], q) for a, q in zip(yaw, quat0)])

    insert_xy = np.array([HOLE_XY, HOLE_XY + [0.0, 0.003]])
    insert_q = np.array([tool_target_posture(model, [x, y, HOLE_TOP + 0.005]) for x, y in insert_xy])
    ins_pos, ins_quat = native_tool_poses(model, insert_q)

    qpos = np.vstack([ALL_STARTS, insert_q])
    n_worlds = len(qpos)
    mocap = np.zeros((n_worlds, 1, 3))
    mocap[:N_TRACK, 0] = [5.0, 0.0, 0.0]
    mocap[N_TRACK:, 0] = [*HOLE_XY, 0.0]
    stiffness = np.tile([400.0, 400.0, 400.0, 50.0, 50.0, 50.0], (n_worlds, 1))
    stiffness[N_TRACK:] = PEG_STIFFNESS
    wrench = np.zeros((n_worlds, 6))
    wrench[N_TRACK:, 2] = -5.0
    task = make_task((np.vstack([pos0, ins_pos]), np.vstack([quat0, ins_quat])),
                     (np.vstack([goal_pos, ins_pos]), np.vstack([goal_quat, ins_quat])),
                     wrench, stiffness, qpos)
    run, cfg = make_scripted_rollout(model, int(round(TRACK_SECONDS / model.opt.timestep)))
    final, trace = run(put_worlds(model, qpos, mocap_pos=mocap), task)
    return dict(trace=jax.tree.map(np.asarray, trace), goal_pos=goal_pos, goal_quat=goal_quat)


def test_tracking_reaches_goal_from_every_start_within_2mm_1deg_in_4s(peg_scene_run):
    pos = peg_scene_run["trace"].tool_pos[-1, :N_TRACK]
    quat = peg_scene_run["trace"].tool_quat[-1, :N_TRACK]
    pos_err = np.linalg.norm(pos - peg_scene_run["goal_pos"], axis=1)
    cos_half = np.clip(np.abs(np.sum(quat * peg_scene_run["goal_quat"], axis=1)), 0.0, 1.0)
    angle_err = np.degrees(2.0 * np.arccos(cos_half))
    assert np.all(pos_err < 0.002), f"position errors (mm): {np.round(pos_err * 1e3, 2)}"
    assert np.all(angle_err < 1.0), f"orientation errors (deg): {np.round(angle_err, 2)}"
    # It did move: halfway through, every tool is well away from its start.
    mid = peg_scene_run["trace"].tool_pos[len(peg_scene_run["trace"].tool_pos) // 2, :N_TRACK]
    assert np.all(np.linalg.norm(mid - peg_scene_run["trace"].tool_pos[0, :N_TRACK], axis=1) > 0.1)


def test_aligned_peg_pressed_with_5N_slides_in_past_1cm(peg_scene_run):
    depth = HOLE_TOP - peg_scene_run["trace"].tool_pos[-1, N_TRACK, 2]
    assert depth > 0.01, f"aligned peg reached depth {depth:.4f} m"


def test_peg_offset_3mm_stays_on_the_rim(peg_scene_run):
    depth = HOLE_TOP - peg_scene_run["trace"].tool_pos[:, N_TRACK + 1, 2]
    assert depth.max() < 0.002, f"offset peg went {depth.max():.4f} m into the hole"
    # and it was pressed onto the rim, not held above it
    assert abs(depth[-1]) < 0.002


@pytest.fixture(scope="module")
def push_scene_run():
    """Two worlds of the push scene, 2.5 s: (0) the pusher lowered onto free table with zero z
    stiffness and -5 N; (1) the pusher sweeping 0.2 m in +y through the prism's long edge."""
    model = load_scene("push")
    object_start = model.body("object").pos.copy()
    press_q = tool_target_posture(model, [0.45, 0.15, 0.02])
    push_q = tool_target_posture(model, [object_start[0], object_start[1] - 0.15, 0.03])
    qpos_arm = np.array([press_q, push_q])
    pos0, quat0 = native_tool_poses(model, qpos_arm)
    goal_pos = pos0.copy()
    goal_pos[1, 1] += 0.2
    stiffness = np.array([[400.0, 400.0, 0.0, 50.0, 50.0, 50.0], PUSH_STIFFNESS])
    wrench = np.zeros((2, 6))
    wrench[0, 2] = -5.0
    task = make_task((pos0, quat0), (goal_pos, quat0), wrench, stiffness, qpos_arm)
    key_qpos = model.key("home").qpos
    qpos = np.array([np.concatenate([q, key_qpos[7:]]) for q in qpos_arm])
    run, _ = make_scripted_rollout(model, 1250)
    final, trace = run(put_worlds(model, qpos), task)
    return model, final, jax.tree.map(np.asarray, trace)


def test_pusher_rests_on_table_with_5N_contact_force(push_scene_run):
    from mujoco import mjx

    model, final, trace = push_scene_run
    data = mjx.get_data(model, final)[0]
    # Measured independently of MJX's solver: native MuJoCo solves the contacts of the final
    # state again under the same torques.
    mujoco.mj_forward(model, data)
    tool, table = model.geom("tool_geom").id, model.geom("table").id
    force = np.zeros(6)
    normal = 0.0
    for i in range(data.ncon):
        c = data.contact[i]
        if {c.geom1, c.geom2} == {tool, table}:
            mujoco.mj_contactForce(model, data, i, force)
            normal += force[0]
    assert abs(normal - 5.0) < 1.0, f"contact normal force {normal:.2f} N"
    assert abs(trace.tool_pos[-1, 0, 2]) < 0.002  # resting on the table plane z = 0


def test_pusher_moves_the_object_and_its_pose_is_reported(push_scene_run):
    from mujoco import mjx

    model, final, _ = push_scene_run
    obj = model.body("object").id
    start = model.body("object").pos
    pos = np.asarray(final.xpos[1, obj])
    quat = np.asarray(final.xquat[1, obj])
    assert pos[1] - start[1] > 0.08, f"object moved only {pos[1] - start[1]:.3f} m in +y"
    assert abs(pos[2] - start[2]) < 0.003  # still on the table
    # Reported pose = native MuJoCo kinematics of the same state = the free joint's qpos.
    data = mjx.get_data(model, final)[1]
    mujoco.mj_kinematics(model, data)
    np.testing.assert_allclose(pos, data.xpos[obj], atol=1e-5)
    np.testing.assert_allclose(quat, data.xquat[obj], atol=1e-5)
    qadr = model.jnt_qposadr[model.body_jntadr[obj]]
    np.testing.assert_allclose(pos, data.qpos[qadr:qadr + 3], atol=1e-5)
    # The object was not touched in world 0.
    np.testing.assert_allclose(np.asarray(final.xpos[0, obj]), start, atol=1e-3)
