"""Damped-least-squares inverse kinematics of the tool site over native MuJoCo (host side; used to
generate the start postures in postures.py and by tests)."""

from __future__ import annotations

import mujoco
import numpy as np

from mjxskill.sim.controller_config import N_ARM
from mjxskill.sim.scene import TOOL_SITE

# Tool pointing straight down (site z axis = world -z): rotation by pi about y, the natural
# orientation of a planar iiwa posture (q1 = q3 = q5 = q7 = 0, q6 = pi - q2 + q4).
DOWN_QUAT = np.array([0.0, 0.0, 1.0, 0.0])


def tool_down_quat(yaw: float) -> np.ndarray:
    """Quaternion (4,) of the tool pointing down, turned by ``yaw`` (rad) about the world z."""
    q = np.zeros(4)
    mujoco.mju_mulQuat(q, np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]), DOWN_QUAT)
    return q


def inverse_kinematics(model: mujoco.MjModel, target_pos, target_quat, q_init, q_rest=None,
                       site: str = TOOL_SITE, damping: float = 1e-3, rest_gain: float = 0.1,
                       iterations: int = 500, tol: float = 1e-7):
    """Arm posture (7,) putting ``site`` at target_pos (3,) with orientation target_quat (4,).

    Damped least squares from ``q_init`` (7,), with a small pull toward ``q_rest`` in the
    Jacobian's nullspace (chooses among redundant solutions) and clipping to the joint limits.
    Raises ValueError when it does not converge to 0.1 mm and 0.01 degrees.
    """
    data = mujoco.MjData(model)
    site_id = model.site(site).id
    q = np.array(q_init, dtype=np.float64)
    q_rest = q.copy() if q_rest is None else np.asarray(q_rest, dtype=np.float64)
    lo, hi = model.jnt_range[:N_ARM, 0], model.jnt_range[:N_ARM, 1]
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for it in range(iterations):
        data.qpos[:N_ARM] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, data.site_xmat[site_id])
        neg, dq_quat, rot_err = np.zeros(4), np.zeros(4), np.zeros(3)
        mujoco.mju_negQuat(neg, quat)
        mujoco.mju_mulQuat(dq_quat, np.asarray(target_quat, dtype=np.float64), neg)
        mujoco.mju_quat2Vel(rot_err, dq_quat, 1.0)
        err = np.concatenate([np.asarray(target_pos) - data.site_xpos[site_id], rot_err])
        if np.linalg.norm(err[:3]) < tol and np.linalg.norm(err[3:]) < tol:
            break
        mujoco.mj_jacSite(model, data, jacp, jacr, site_id)
        jac = np.vstack([jacp, jacr])[:, :N_ARM]
        jjt = jac @ jac.T + damping * np.eye(6)
        step = jac.T @ np.linalg.solve(jjt, err)
        projector = np.eye(N_ARM) - jac.T @ np.linalg.solve(jjt, jac)
        # The damped projector is not exactly the nullspace: pull toward the rest posture only in
        # the first half, then converge on the target alone.
        pull = rest_gain if it < iterations // 2 else 0.0
        q = np.clip(q + step + pull * projector @ (q_rest - q), lo, hi)
    if np.linalg.norm(err[:3]) > 1e-4 or np.linalg.norm(err[3:]) > np.radians(0.01):
        raise ValueError(
            f"inverse_kinematics did not converge for target_pos={list(target_pos)}: "
            f"position error {np.linalg.norm(err[:3]):.2e} m, rotation error {np.linalg.norm(err[3:]):.2e} rad")
    return q
