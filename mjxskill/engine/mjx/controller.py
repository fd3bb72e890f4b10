"""Cartesian impedance controller for the iiwa, one control step in pure JAX.

    tau = J^T (-K x_e - D J qdot) + J^T F_ext + N (k_ns (q_ns - q) - 2 sqrt(k_ns) qdot) + b(q, qdot)

with J the 6x7 site Jacobian (translation; rotation, world frame), x_e the pose error of the tool
site (position; rotation vector of q_cur * q_ref^-1), D = 2 sqrt(K) (unit-mass critical damping,
as SkiREIL and the Franka example controller), N = I - J^T (J J^T + lambda I)^-1 J the nullspace
projector and b = qfrc_bias (gravity and Coriolis: exact compensation of the model). The commanded
stiffness and wrench are rate limited (500 /s and 10 N/s), the torque change is limited to
2 Nm per step and the torque saturated at the joint limits. Written for one world; batching is a
wrapper (``jax.vmap``).

The controller reads the kinematic quantities a previous ``mjx.step``/``mjx.forward`` left in the
data (site pose, Jacobian, qfrc_bias), i.e. of the state at the start of the last step: one
control period (2 ms) of sensing delay when called after ``mjx.step``, like a real robot.

Command layout (19,): [ref_pos (3), ref_quat (4, w x y z), wrench (6: force xyz, torque xyz,
world frame), stiffness (6: translational xyz, rotational xyz)].
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from mujoco import mjx

from mjxskill.sim.controller_config import COMMAND_SIZE, DEFAULT_STIFFNESS, N_ARM, ControllerConfig, rate_limit
from mjxskill.engine.common.arrays import JAX
from mjxskill.engine.common.rotations import quat_conj, quat_mul, quat_to_rotvec

__all__ = [
    "COMMAND_SIZE", "DEFAULT_STIFFNESS", "N_ARM", "Command", "ControllerConfig", "ControllerState", "impedance_control",
    "init_controller_state", "make_command", "site_jacobian", "split_command", "tool_pose",
]

class ControllerState(NamedTuple):
    """The rate-limited quantities carried from one control step to the next."""

    torque: jnp.ndarray  # (7,) float: torque applied at the previous step, Nm
    stiffness: jnp.ndarray  # (6,) float: stiffness applied at the previous step
    wrench: jnp.ndarray  # (6,) float: feed-forward wrench applied at the previous step


class Command(NamedTuple):
    """The 19-D command split into its parts."""

    pos: jnp.ndarray  # (..., 3) reference position, m, world frame
    quat: jnp.ndarray  # (..., 4) reference orientation, w x y z
    wrench: jnp.ndarray  # (..., 6) force xyz (N), torque xyz (Nm), world frame
    stiffness: jnp.ndarray  # (..., 6) translational xyz (N/m), rotational xyz (Nm/rad)


def make_command(pos, quat, wrench=None, stiffness=None):
    """Packs a command (..., 19); wrench defaults to zero, stiffness to 400 N/m, 50 Nm/rad."""
    pos = jnp.asarray(pos)
    quat = jnp.asarray(quat, dtype=pos.dtype)
    batch = pos.shape[:-1]
    if wrench is None:
        wrench = jnp.zeros(batch + (6,), pos.dtype)
    if stiffness is None:
        stiffness = jnp.broadcast_to(jnp.asarray(DEFAULT_STIFFNESS, pos.dtype), batch + (6,))
    parts = [pos, quat, jnp.asarray(wrench, pos.dtype), jnp.asarray(stiffness, pos.dtype)]
    sizes = [p.shape[-1] for p in parts]
    if sizes != [3, 4, 6, 6]:
        raise ValueError(f"command parts must have sizes [3, 4, 6, 6] (pos, quat, wrench, stiffness), got {sizes}")
    return jnp.concatenate(parts, axis=-1)


def split_command(command) -> Command:
    """Unpacks a (..., 19) command."""
    if command.shape[-1] != COMMAND_SIZE:
        raise ValueError(f"command must have last dimension {COMMAND_SIZE}, got shape {command.shape}")
    return Command(command[..., :3], command[..., 3:7], command[..., 7:13], command[..., 13:19])


def init_controller_state(data: mjx.Data, command) -> ControllerState:
    """State for the first step: the previous torque is the gravity/Coriolis compensation (so the
    2 Nm/step limit does not drop the arm), the stiffness starts at the commanded one and the
    wrench at zero (it ramps up at 10 N/s)."""
    cmd = split_command(command)
    return ControllerState(
        torque=data.qfrc_bias[:N_ARM],
        stiffness=cmd.stiffness,
        wrench=jnp.zeros_like(cmd.wrench),
    )


def tool_pose(cfg: ControllerConfig, model: mjx.Model, data: mjx.Data):
    """Tool site position (3,) and orientation quaternion (4,) in the world frame."""
    pos = data.site_xpos[cfg.site_id]
    quat = quat_mul(data.xquat[cfg.site_body_id], model.site_quat[cfg.site_id])
    return pos, quat


def site_jacobian(cfg: ControllerConfig, model: mjx.Model, data: mjx.Data):
    """(6, 7) Jacobian of the tool site: rows translation xyz, rotation xyz (world frame)."""
    jacp, jacr = mjx.jac(model, data, data.site_xpos[cfg.site_id], cfg.site_body_id)
    return jnp.concatenate([jacp.T, jacr.T], axis=0)[:, :N_ARM]


def impedance_control(
    cfg: ControllerConfig,
    model: mjx.Model,
    data: mjx.Data,
    command,
    nullspace_target,
    state: ControllerState,
):
    """One control step.

    Args:
      cfg: static settings (:meth:`ControllerConfig.from_model`).
      model, data: MJX model and data with kinematics computed.
      command: (19,) see module docstring.
      nullspace_target: (7,) joint posture the nullspace term pulls toward (the start posture).
      state: rate-limited quantities of the previous step.
    Returns:
      tau (7,) joint torques to apply, new ControllerState.
    """
    cmd = split_command(command)
    dtype = data.qpos.dtype
    stiffness = rate_limit(state.stiffness, cmd.stiffness, cfg.stiffness_rate * cfg.dt, JAX)
    wrench = rate_limit(state.wrench, cmd.wrench, cfg.wrench_rate * cfg.dt, JAX)

    q, qd = data.qpos[:N_ARM], data.qvel[:N_ARM]
    jac = site_jacobian(cfg, model, data)
    pos, quat = tool_pose(cfg, model, data)
    pos_err = pos - cmd.pos
    rot_err = quat_to_rotvec(quat_mul(quat, quat_conj(cmd.quat)))
    pose_err = jnp.concatenate([pos_err, rot_err])
    twist = jac @ qd
    damping = 2.0 * jnp.sqrt(jnp.maximum(stiffness, 0.0))
    task_force = -stiffness * pose_err - damping * twist + wrench

    jjt = jac @ jac.T + cfg.pinv_damping * jnp.eye(6, dtype=dtype)
    projector = jnp.eye(N_ARM, dtype=dtype) - jac.T @ jnp.linalg.solve(jjt, jac)
    k_ns = cfg.nullspace_stiffness
    nullspace = projector @ (k_ns * (nullspace_target - q) - 2.0 * np.sqrt(k_ns) * qd)

    tau = jac.T @ task_force + nullspace + data.qfrc_bias[:N_ARM]
    tau = rate_limit(state.torque, tau, cfg.torque_step, JAX)
    limit = jnp.asarray(cfg.torque_limit, dtype)
    tau = jnp.clip(tau, -limit, limit)
    return tau, ControllerState(tau, stiffness, wrench)
