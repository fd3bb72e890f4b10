"""The impedance law of :mod:`mjxskill.engine.mjx.controller` once more, in numpy over native MuJoCo.

Independent of the JAX version where it can be: the Jacobian comes from ``mj_jacSite``, the site
orientation from ``site_xmat`` through ``mju_mat2Quat``, the rotation error from
``mju_mulQuat``/``mju_negQuat``/``mju_quat2Vel``, the bias forces from ``qfrc_bias``. It is the
reference the tests compare the JAX controller with, and the baseline of benchmarks/batching.py.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.rotations import quat_mul
from mjxskill.sim.controller_config import N_ARM, ControllerConfig


class NativeControllerState:
    """Mutable host-side counterpart of ControllerState (torque (7,), stiffness (6,), wrench (6,))."""

    def __init__(self, torque, stiffness, wrench):
        self.torque = np.array(torque, dtype=np.float64)
        self.stiffness = np.array(stiffness, dtype=np.float64)
        self.wrench = np.array(wrench, dtype=np.float64)


def _rate_limit(previous, target, max_delta):
    return previous + np.clip(target - previous, -max_delta, max_delta)


def native_impedance_control(cfg: ControllerConfig, model, data, command, nullspace_target, state):
    """Same contract as controller.impedance_control on a native MjModel/MjData (kinematics
    computed). Returns tau (7,) and a new NativeControllerState."""
    command = np.asarray(command, dtype=np.float64)
    ref_pos, ref_quat = command[:3], command[3:7]
    cmd_wrench, cmd_stiffness = command[7:13], command[13:19]
    stiffness = _rate_limit(state.stiffness, cmd_stiffness, cfg.stiffness_rate * cfg.dt)
    wrench = _rate_limit(state.wrench, cmd_wrench, cfg.wrench_rate * cfg.dt)

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
    tau = _rate_limit(state.torque, tau, cfg.torque_step)
    limit = np.asarray(cfg.torque_limit)
    tau = np.clip(tau, -limit, limit)
    return tau, NativeControllerState(tau, stiffness, wrench)


def native_rollout(cfg: ControllerConfig, model, data, command, nullspace_target, n_steps: int):
    """Steps ``data`` in place ``n_steps`` times under a constant command (Python loop:
    controller then mj_step). Returns the final NativeControllerState."""
    mujoco.mj_forward(model, data)
    state = NativeControllerState(data.qfrc_bias[:N_ARM], np.asarray(command)[13:19], np.zeros(6))
    for _ in range(n_steps):
        tau, state = native_impedance_control(cfg, model, data, command, nullspace_target, state)
        data.ctrl[:N_ARM] = tau
        mujoco.mj_step(model, data)
    return state




def _quat_to_rotvec_rows(q):
    """Row-wise ``mju_quat2Vel(q, dt=1)``: axis times angle, the angle wrapped into (-pi, pi]."""
    norm = np.sqrt(q[:, 1] * q[:, 1] + q[:, 2] * q[:, 2] + q[:, 3] * q[:, 3])
    tiny = norm < 1e-15  # mjMINVAL: MuJoCo then takes the x axis (the angle is ~0 anyway)
    axis = np.where(tiny[:, None], np.array([1.0, 0.0, 0.0]), q[:, 1:] / np.where(tiny, 1.0, norm)[:, None])
    # math.atan2 (the C library's), not np.arctan2, whose SIMD loops may round differently
    angle = 2.0 * np.array([math.atan2(n, w) for n, w in zip(norm.tolist(), q[:, 0].tolist())])
    angle = np.where(angle > np.pi, angle - 2.0 * np.pi, angle)
    return axis * angle[:, None]


class BatchedControllerState:
    """torque (N, 7), stiffness (N, 6), wrench (N, 6): the rate-limited quantities of N arms."""

    def __init__(self, torque, stiffness, wrench):
        self.torque, self.stiffness, self.wrench = torque, stiffness, wrench


def _row_dot(a, b):
    """sum_k a[:, k] * b[:, k] over the last axis, added left to right."""
    acc = a[:, 0] * b[:, 0]
    for k in range(1, a.shape[1]):
        acc = acc + a[:, k] * b[:, k]
    return acc


def batched_impedance_control(cfg: ControllerConfig, jac, site_pos, site_quat, q, qd, bias, ref_pos, ref_quat,
                              cmd_wrench, cmd_stiffness, nullspace_target, state: BatchedControllerState):
    """``native_impedance_control`` for N arms at once, every quantity with a leading (N,) axis:
    jac (N, 6, 7) site Jacobians, site_pos (N, 3), site_quat (N, 4), q, qd, bias (N, 7) joint
    positions, velocities and ``qfrc_bias``, ref_pos (N, 3), ref_quat (N, 4), cmd_wrench and
    cmd_stiffness (N, 6), nullspace_target (N, 7). Returns tau (N, 7) and the new state.

    The law's reference for the compiled one (``mjxskill.engine.native.kernels.impedance_rows``),
    written with one numpy operation per scalar operation of it, in its order (sums left to
    right, the damped pseudo-inverse through a Cholesky factorization of the symmetric positive
    definite J J^T + lambda I), so that the two agree bit for bit; the plain loop's law, with
    BLAS and LAPACK, agrees with both to rounding. Rows never mix."""
    n = len(jac)
    stiffness = _rate_limit(state.stiffness, cmd_stiffness, cfg.stiffness_rate * cfg.dt)
    wrench = _rate_limit(state.wrench, cmd_wrench, cfg.wrench_rate * cfg.dt)
    ref_inv = ref_quat * np.array([1.0, -1.0, -1.0, -1.0])
    rot_err = _quat_to_rotvec_rows(quat_mul(site_quat, ref_inv, HOST))
    pose_err = np.concatenate([site_pos - ref_pos, rot_err], axis=1)
    twist = np.stack([_row_dot(jac[:, k], qd) for k in range(6)], axis=1)
    task_force = -stiffness * pose_err - 2.0 * np.sqrt(np.maximum(stiffness, 0.0)) * twist + wrench
    chol = np.zeros((n, 6, 6))  # lower factor L of J J^T + lambda I = L L^T
    for a in range(6):
        for b in range(a + 1):
            acc = _row_dot(jac[:, a], jac[:, b]) + (cfg.pinv_damping if a == b else 0.0)
            for c in range(b):
                acc = acc - chol[:, a, c] * chol[:, b, c]
            chol[:, a, b] = np.sqrt(acc) if a == b else acc / chol[:, b, b]
    x = np.zeros((n, 6, N_ARM))  # (J J^T + lambda I)^-1 J: forward, then back substitution
    for a in range(6):
        acc = jac[:, a, :]
        for c in range(a):
            acc = acc - chol[:, a, c, None] * x[:, c, :]
        x[:, a, :] = acc / chol[:, a, a, None]
    for a in range(5, -1, -1):
        acc = x[:, a, :]
        for c in range(a + 1, 6):
            acc = acc - chol[:, c, a, None] * x[:, c, :]
        x[:, a, :] = acc / chol[:, a, a, None]
    k_ns = cfg.nullspace_stiffness
    drive = k_ns * (nullspace_target - q) - 2.0 * math.sqrt(k_ns) * qd
    tau = np.empty((n, N_ARM))
    for j in range(N_ARM):
        nullspace = drive[:, j]
        for c in range(N_ARM):
            nullspace = nullspace - _row_dot(jac[:, :, j], x[:, :, c]) * drive[:, c]
        total = bias[:, j] + nullspace
        for k in range(6):
            total = total + jac[:, k, j] * task_force[:, k]
        tau[:, j] = total
    tau = _rate_limit(state.torque, tau, cfg.torque_step)
    limit = np.asarray(cfg.torque_limit)
    tau = np.clip(tau, -limit, limit)
    return tau, BatchedControllerState(tau, stiffness, wrench)
