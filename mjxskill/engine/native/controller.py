"""The impedance law of :mod:`mjxskill.engine.mjx.controller` once more, in numpy over native MuJoCo.

Independent of the JAX version where it can be: the Jacobian comes from ``mj_jacSite``, the site
orientation from ``site_xmat`` through ``mju_mat2Quat``, the rotation error from
``mju_mulQuat``/``mju_negQuat``/``mju_quat2Vel``, the bias forces from ``qfrc_bias``. It is the
reference the tests compare the JAX controller with, and the law a plain episode steps with
(``NativeEpisode.plain_steps``: ``NativeRollout.trace``, and a world that starts from a
non-finite state). The same law vectorized over episodes, operation for operation as the
compiled kernel, is ``mjxskill.engine.native_reference.batched_impedance_control``.
"""

from __future__ import annotations


import mujoco
import numpy as np

from mjxskill.sim.controller_config import N_ARM, ControllerConfig, rate_limit


class NativeControllerState:
    """Mutable host-side counterpart of ControllerState (torque (7,), stiffness (6,), wrench (6,))."""

    def __init__(self, torque, stiffness, wrench):
        self.torque = np.array(torque, dtype=np.float64)
        self.stiffness = np.array(stiffness, dtype=np.float64)
        self.wrench = np.array(wrench, dtype=np.float64)


def native_impedance_control(cfg: ControllerConfig, model, data, command, nullspace_target, state):
    """Same contract as controller.impedance_control on a native MjModel/MjData (kinematics
    computed). Returns tau (7,) and a new NativeControllerState."""
    command = np.asarray(command, dtype=np.float64)
    ref_pos, ref_quat = command[:3], command[3:7]
    cmd_wrench, cmd_stiffness = command[7:13], command[13:19]
    stiffness = rate_limit(state.stiffness, cmd_stiffness, cfg.stiffness_rate * cfg.dt, np)
    wrench = rate_limit(state.wrench, cmd_wrench, cfg.wrench_rate * cfg.dt, np)

    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jacp, jacr, cfg.site_id)
    jac = np.vstack([jacp, jacr])[:, :N_ARM]

    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, data.site_xmat[cfg.site_id])
    ref_inv = np.zeros(4)
    mujoco.mju_negQuat(ref_inv, ref_quat)
    err_quat = np.zeros(4)
    mujoco.mju_mulQuat(err_quat, quat, ref_inv)
    rot_err = np.zeros(3)
    mujoco.mju_quat2Vel(rot_err, err_quat, 1.0)
    pose_err = np.concatenate([data.site_xpos[cfg.site_id] - ref_pos, rot_err])

    q, qd = data.qpos[:N_ARM], data.qvel[:N_ARM]
    twist = jac @ qd
    task_force = -stiffness * pose_err - 2.0 * np.sqrt(np.maximum(stiffness, 0.0)) * twist + wrench
    jjt = jac @ jac.T + cfg.pinv_damping * np.eye(6)
    projector = np.eye(N_ARM) - jac.T @ np.linalg.solve(jjt, jac)
    k_ns = cfg.nullspace_stiffness
    nullspace = projector @ (k_ns * (np.asarray(nullspace_target) - q) - 2.0 * np.sqrt(k_ns) * qd)

    tau = jac.T @ task_force + nullspace + data.qfrc_bias[:N_ARM]
    tau = rate_limit(state.torque, tau, cfg.torque_step, np)
    limit = np.asarray(cfg.torque_limit)
    tau = np.clip(tau, -limit, limit)
    return tau, NativeControllerState(tau, stiffness, wrench)
