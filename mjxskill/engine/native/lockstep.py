"""Many native episodes in lockstep: the BT ticks per episode as in the plain loop, the control
steps between two ticks for all episodes at once.

The plain loop spends most of a control step in Python (about 60 us of numpy per 6 us of
``mj_step``; benchmarks/NOTES.md). Here each tick computes every episode's references for the
whole tick at once (``NativeBlackboard.references``), and each control step runs the impedance
law once for all N episodes (``batched_impedance_control``: one numpy operation per quantity,
not per episode); only the Jacobian, the sensor reads and ``mj_step`` remain per episode, and
they are C calls. Each episode keeps its own ``MjModel`` copy (its world's friction) and
``MjData``; rows never mix, so an episode's result does not depend on which episodes share its
batch (tests/test_native_engine.py checks it bit for bit).
"""

from __future__ import annotations

import mujoco
import numpy as np

from mjxskill.engine.native.controller import BatchedControllerState, NativeControllerState, batched_impedance_control
from mjxskill.engine.native.episode import NativeEpisode
from mjxskill.engine.common.types import EpisodeResult
from mjxskill.sim.controller_config import N_ARM


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
