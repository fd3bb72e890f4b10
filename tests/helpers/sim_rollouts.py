"""Scripted rollouts shared by the simulation tests: a reference pose moving along
linear_trajectory(start, goal, t) with a constant stiffness and wrench, per world, stepped with
the JAX controller and mjx.step for a fixed horizon. One jitted function per scene."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from mjxskill.engine.mjx.batching import control_step, put_worlds
from mjxskill.engine.mjx.controller import ControllerConfig, init_controller_state, make_command, tool_pose
from mjxskill.sim.inverse_kinematics import inverse_kinematics, tool_down_quat
from mjxskill.engine.mjx.motion import Pose, linear_trajectory
from mjxskill.sim.postures import HOME
from mjxskill.sim.scene import load_scene


class Task(NamedTuple):
    """Per-world script (leading axis W on every field)."""

    start: Pose  # pos (W, 3), quat (W, 4)
    goal: Pose
    wrench: jnp.ndarray  # (W, 6)
    stiffness: jnp.ndarray  # (W, 6)
    nullspace_target: jnp.ndarray  # (W, 7)


class Trace(NamedTuple):
    tool_pos: jnp.ndarray  # (T, W, 3) per step, after the step's kinematics
    tool_quat: jnp.ndarray  # (T, W, 4)


def make_scripted_rollout(model: mujoco.MjModel, n_steps: int):
    """jitted f(data (W,...), task) -> (final data, Trace); vmapped over worlds."""
    cfg = ControllerConfig.from_model(model)
    mx = mjx.put_model(model)

    def one_world(data, task: Task):
        command0 = make_command(task.start.pos, task.start.quat, task.wrench, task.stiffness)
        state = init_controller_state(data, command0)

        def body(carry, k):
            d, s = carry
            ref = linear_trajectory(task.start, task.goal, k * cfg.dt)
            command = make_command(ref.pos, ref.quat, task.wrench, task.stiffness)
            d, s = control_step(cfg, mx, d, command, task.nullspace_target, s)
            return (d, s), (d.site_xpos[cfg.site_id], tool_pose(cfg, mx, d)[1])

        (data, _), (pos, quat) = jax.lax.scan(body, (data, state), jnp.arange(n_steps))
        return data, Trace(pos, quat)

    def run(data, task):
        final, trace = jax.vmap(one_world)(data, task)
        return final, Trace(*(jnp.swapaxes(x, 0, 1) for x in trace))

    return jax.jit(run), cfg


def tool_target_posture(model, pos, yaw=0.0):
    """Arm posture with the tool tip at pos (3,), pointing down, turned by yaw."""
    seed = HOME.copy()
    seed[0] = np.arctan2(pos[1], pos[0])
    seed[5] = np.pi - seed[1] + seed[3]
    return inverse_kinematics(model, pos, tool_down_quat(yaw), seed, seed)


def make_task(starts, goals, wrench, stiffness, nullspace_target) -> Task:
    f32 = lambda x: jnp.asarray(np.asarray(x), jnp.float32)  # noqa: E731
    return Task(Pose(f32(starts[0]), f32(starts[1])), Pose(f32(goals[0]), f32(goals[1])),
                f32(wrench), f32(stiffness), f32(nullspace_target))


def native_tool_poses(model, qpos):
    """Tool site positions (W, 3) and quaternions (W, 4) of arm postures qpos (W, 7), native."""
    data = mujoco.MjData(model)
    site = model.site("tool").id
    pos, quat = [], []
    for q in qpos:
        data.qpos[:7] = q
        mujoco.mj_kinematics(model, data)
        quat_w = np.zeros(4)
        mujoco.mju_mat2Quat(quat_w, data.site_xmat[site])
        pos.append(data.site_xpos[site].copy())
        quat.append(quat_w)
    return np.array(pos), np.array(quat)


__all__ = ["load_scene", "put_worlds", "make_scripted_rollout", "make_task", "tool_target_posture",
           "native_tool_poses", "Task", "Trace"]
