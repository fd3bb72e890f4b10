"""The native engine's references: what the tests and benchmarks check the production engine
(``mjxskill.engine.native``) against. No module of the package imports this one
(tests/project/test_layout.py).

- ``run_plain``: a call's episodes one after another in the plain loop
  (``NativeRollout.run_episode``: one control step at a time, the scalar numpy law with MuJoCo's
  own Jacobian and quaternion functions), how a user without this project would write it: the
  reference of whole episodes, to rounding (tests/engine/native/test_engine.py).
- ``run_lockstep``: the episodes stepped together, the BT ticks per episode as in the plain loop
  and each control step's impedance law once for all N episodes in numpy
  (``batched_impedance_control``, one numpy operation per scalar operation of the compiled
  kernel ``mjxskill.engine.native.kernels.impedance_rows``, in its order: sums left to right, the
  damped pseudo-inverse applied to one vector through a Cholesky factorization of the symmetric
  positive definite J J^T + lambda I). Each episode keeps its own ``MjModel`` copy (its world's
  friction) and ``MjData``, rows never mix, and the compiled engine's episodes equal its results
  bit for bit (tests/engine/native/test_batched.py); the plain loop's law, with BLAS and LAPACK,
  agrees with both to rounding.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.rotations import quat_mul
from mjxskill.engine.common.types import EpisodeResult, RolloutOutput
from mjxskill.engine.common.worlds import Worlds
from mjxskill.engine.native.controller import NativeControllerState
from mjxskill.engine.native.episode import NativeEpisode
from mjxskill.engine.native.rollout import NativeRollout
from mjxskill.sim.controller_config import N_ARM, ControllerConfig, rate_limit


def run_plain(engine: NativeRollout, params, worlds: Worlds) -> RolloutOutput:
    """``engine.run_worlds(params, worlds)`` with every episode run in the plain loop, one after
    another, in this process."""
    return engine.gather(params, worlds, lambda p, w: [engine.run_episode(p[i], _world(w, i)) for i in range(len(p))])


def run_lockstep(engine, params: np.ndarray, worlds) -> list[EpisodeResult]:
    """Episodes of ``engine`` (a ``NativeRollout``) for params (N, P) in ``worlds`` (leading
    shape (N,), numpy fields), stepped together. Returns the N results in order."""
    n = len(params)
    episodes = [
        NativeEpisode(engine, params[i], _world(worlds, i), engine.mj_model.__copy__()) for i in range(n)
    ]
    spec, cfg = engine.setup, engine.setup.ctrl
    site, steps, nv = cfg.site_id, spec.steps_per_tick, engine.mj_model.nv
    for t in range(spec.ticks):
        alive = [e for e in episodes if not e.diverged]
        if not alive:
            break
        for e in alive:
            e.begin_tick()
        _control_steps(alive, cfg, site, steps, nv)
        for e in alive:
            e.end_tick(t)
    return [e.result() for e in episodes]


def _world(worlds, i: int):
    return type(worlds)(*(np.asarray(x)[i] for x in worlds))


def _control_steps(episodes: list[NativeEpisode], cfg, site: int, steps: int, nv: int) -> None:
    """One tick's control steps of every episode in ``episodes``."""
    m = len(episodes)
    refs = [e.bb.references(steps, cfg.dt) for e in episodes]
    ref_pos = np.stack([r[0] for r in refs], axis=1)  # (steps, m, 3)
    ref_quat = np.stack([r[1] for r in refs], axis=1)  # (steps, m, 4)
    cmd_wrench = np.stack([e.bb.wrench for e in episodes])
    cmd_stiffness = np.stack([e.bb.stiffness for e in episodes])
    nullspace_target = np.stack([e.nullspace_target for e in episodes])
    state = BatchedControllerState(
        np.stack([e.cstate.torque for e in episodes]),
        np.stack([e.cstate.stiffness for e in episodes]),
        np.stack([e.cstate.wrench for e in episodes]),
    )
    jac_full = np.zeros((m, 6, nv))  # rows 0-2 translation, 3-5 rotation (mj_jacSite writes both)
    jac = jac_full[:, :, :N_ARM]
    site_pos, site_quat = np.zeros((m, 3)), np.zeros((m, 4))
    q, qd, bias = np.zeros((m, N_ARM)), np.zeros((m, N_ARM)), np.zeros((m, N_ARM))
    # Views into each episode's MjData, made once per tick (an attribute read makes a new view).
    views = [
        (e.model, e.data, e.data.site_xpos[site], e.data.site_xmat[site], e.data.qpos[:N_ARM], e.data.qvel[:N_ARM],
         e.data.qfrc_bias[:N_ARM], e.data.ctrl[:N_ARM])
        for e in episodes
    ]
    # The measured contact force: the tool's touch sensors, which mj_step computes; one read per
    # episode and step (of the sensor when there is one, as there is for a single tool body).
    sensors = list(episodes[0].engine.setup.bindings.force_sensors) if episodes else []
    readings = [e.data.sensordata[sensors[0]:sensors[0] + 1] if len(sensors) == 1 else None for e in episodes]
    force = np.zeros((steps, m))
    for k in range(steps):
        for i, (model, data, xpos, xmat, qpos, qvel, qbias, _) in enumerate(views):
            mujoco.mj_jacSite(model, data, jac_full[i, :3], jac_full[i, 3:], site)
            site_pos[i] = xpos
            mujoco.mju_mat2Quat(site_quat[i], xmat)
            q[i] = qpos
            qd[i] = qvel
            bias[i] = qbias
        tau, state = batched_impedance_control(
            cfg, jac, site_pos, site_quat, q, qd, bias, ref_pos[k], ref_quat[k], cmd_wrench, cmd_stiffness,
            nullspace_target, state,
        )
        row = force[k]
        for i, (model, data, *_, ctrl) in enumerate(views):
            ctrl[:] = tau[i]
            mujoco.mj_step(model, data)
            reading = readings[i]
            row[i] = reading[0] if reading is not None else data.sensordata[sensors].sum()
    sums, peaks = force.sum(axis=0), force.max(axis=0, initial=0.0)
    for i, e in enumerate(episodes):
        e.cstate = NativeControllerState(state.torque[i], state.stiffness[i], state.wrench[i])
        e.tick_force = (float(sums[i]), float(peaks[i]))


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
    right, the damped pseudo-inverse applied to one vector through a Cholesky factorization of
    the symmetric positive definite J J^T + lambda I), so that the two agree bit for bit; the
    plain loop's law, with BLAS and LAPACK, agrees with both to rounding. Rows never mix."""
    n = len(jac)
    stiffness = rate_limit(state.stiffness, cmd_stiffness, cfg.stiffness_rate * cfg.dt, np)
    wrench = rate_limit(state.wrench, cmd_wrench, cfg.wrench_rate * cfg.dt, np)
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
    k_ns = cfg.nullspace_stiffness
    drive = k_ns * (nullspace_target - q) - 2.0 * math.sqrt(k_ns) * qd
    # (I - J^T x) drive = drive - J^T (x drive), x = (J J^T + lambda I)^-1 J: x drive is one
    # solve of J drive, forward then back substitution
    x_drive = np.stack([_row_dot(jac[:, a, :], drive) for a in range(6)], axis=1)
    for a in range(6):
        acc = x_drive[:, a]
        for c in range(a):
            acc = acc - chol[:, a, c] * x_drive[:, c]
        x_drive[:, a] = acc / chol[:, a, a]
    for a in range(5, -1, -1):
        acc = x_drive[:, a]
        for c in range(a + 1, 6):
            acc = acc - chol[:, c, a] * x_drive[:, c]
        x_drive[:, a] = acc / chol[:, a, a]
    tau = np.empty((n, N_ARM))
    for j in range(N_ARM):
        total = bias[:, j] + (drive[:, j] - _row_dot(jac[:, :, j], x_drive))
        for k in range(6):
            total = total + jac[:, k, j] * task_force[:, k]
        tau[:, j] = total
    tau = rate_limit(state.torque, tau, cfg.torque_step, np)
    limit = np.asarray(cfg.torque_limit)
    tau = np.clip(tau, -limit, limit)
    return tau, BatchedControllerState(tau, stiffness, wrench)
