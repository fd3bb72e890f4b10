"""The native-MuJoCo baseline: the episodes of a compiled rollout, run as a user without this
project would write them, in a plain single-process Python loop.

Per BT tick: every leaf's status in Python (``mjxskill.native.leaves``), one tick of the
reference interpreter (``mjxskill.ebt.interpreter.Interpreter``), the active leaves' effects,
then ``steps_per_tick`` control steps of ``native_impedance_control`` + ``mujoco.mj_step``, then
the tick's rewards in numpy. Same MJCF model and timestep, same worlds (``mjxskill.rollout.worlds``),
same world-model poses for the skills, same divergence containment (``mjxskill.rollout.types``);
float64 throughout where MJX runs float32. Nothing of the compiled rollout or of MJX is imported:
this engine is the independent reference the compiled one is tested against.

    native = NativeRollout(scn, task, worlds=7)           # as compile_rollout(scn, task, worlds=7)
    out = native.run_worlds(params, native.sample_worlds(key, len(params)))
    out.objectives, out.success, out.metrics              # as RolloutOutput, numpy arrays
"""

from __future__ import annotations

import copy
import math

import jax
import mujoco
import numpy as np

from mjxskill.ebt.interpreter import Interpreter, TickResult
from mjxskill.ebt.nodes import Status
from mjxskill.native.controller import NativeControllerState, native_impedance_control
from mjxskill.native.leaves import NativeBlackboard, build_native_leaves
from mjxskill.native.motion import quat_angle
from mjxskill.native.rewards import NativeObservation, build_native_terms
from mjxskill.rollout.bindings import FREE, MOCAP, nominal_poses
from mjxskill.rollout.types import (
    MAX_QVEL,
    MIN_OBJECT_Z,
    EpisodeResult,
    RolloutOutput,
    TickRecord,
    episode_setup,
    objective_matrix,
    summarize,
)
from mjxskill.rollout.worlds import Worlds, make_sampler, sample_worlds, worlds_per_config
from mjxskill.sim.controller_config import N_ARM

def _live_nodes(interp: Interpreter, result: TickResult) -> set[int]:
    """Nodes that carry on at the next tick: ticked, and they and all ancestors RUNNING."""
    live, stack = set(), [0]
    while stack:
        nid = stack.pop()
        if result.node_status.get(nid) == Status.RUNNING:
            live.add(nid)
            stack.extend(interp.children[nid])
    return live


class NativeRollout:
    """The episodes of ``task`` in ``scn`` on native MuJoCo (arguments as ``compile_rollout``;
    nothing is compiled)."""

    def __init__(self, scn, task=None, *, worlds: int | None = None, episode_seconds: float | None = None,
                 start_configs: np.ndarray | None = None, mj_model: mujoco.MjModel | None = None):
        if task is None:
            from mjxskill.task import plan_task

            task = plan_task(scn)
        if mj_model is None:
            from mjxskill.sim.model import load_model

            mj_model = load_model(scn)
        seconds = scn.episode_seconds if episode_seconds is None else float(episode_seconds)
        self.scenario, self.task = scn, task
        self.spec = episode_setup(scn, task, mj_model, seconds)
        self.worlds = scn.randomization.n_worlds if worlds is None else int(worlds)
        self.sampler = make_sampler(scn, self.spec.bindings, start_configs)
        sampler, n_worlds = self.sampler, self.worlds
        # The compiled rollout's sampling program, written the same way: the same worlds, bit for bit.
        self._sample = jax.jit(lambda key, batch: sample_worlds(sampler, key, (batch, n_worlds)), static_argnums=1)
        self.model = mj_model
        self.base_pair_friction = self.model.pair_friction.copy()
        self.tree = task.tree
        self.interp = Interpreter(self.tree)
        self.leaf_ids = [i for i, n in enumerate(self.interp.nodes) if n.is_leaf]
        self.leaf_position = {nid: k for k, nid in enumerate(self.leaf_ids)}
        nominal_pos, nominal_quat = nominal_poses(self.spec.bindings)
        self.programs = build_native_leaves(
            self.tree.leaves(), task.parameter_names, self.spec.bindings.slot_of, nominal_pos, nominal_quat, 1.0 / scn.bt_hz
        )
        self.terms = build_native_terms(scn, self.spec.bindings.slot_of)
        self.objective_matrix = objective_matrix(self.terms, len(scn.objective_names), np.float64)
        self.reward_names = tuple(t.name for t in self.terms)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return self.task.parameter_names

    def sample_worlds(self, key, batch: int) -> Worlds:
        """The (batch, W) worlds for ``batch`` parameter sets drawn from ``key``: the same as
        the compiled rollout's for the same key, settings and worlds (one shared sampler)."""
        return jax.tree.map(np.asarray, self._sample(key, batch))

    def worlds_per_config(self, key, per_config: int, configs: np.ndarray | None = None) -> Worlds:
        """``per_config`` worlds from each start configuration (as ``Rollout.worlds_per_config``)."""
        sampler = self.sampler if configs is None else self.sampler._replace(configs=np.asarray(configs, np.float32))
        return jax.tree.map(np.asarray, worlds_per_config(sampler, key, per_config))

    @property
    def control_steps_per_episode(self) -> int:
        return self.spec.ticks * self.spec.steps_per_tick

    @property
    def mj_model(self) -> mujoco.MjModel:
        """The native model it simulates (as ``Rollout.mj_model``)."""
        return self.model

    def trace(self, params, world: Worlds):
        """(EpisodeResult, TickRecord) of ``params`` (P,) in one world, as ``Rollout.trace``:
        so an episode renders from either engine (``mjxskill.training.render``)."""
        return self.run_episode(params, world, record=True)

    # -- one episode ------------------------------------------------------------------------

    def _initial_data(self, world) -> mujoco.MjData:
        model, b = self.model, self.spec.bindings
        model.pair_friction[:] = self.base_pair_friction
        if b.randomized_pairs and not math.isnan(float(world.friction)):
            model.pair_friction[list(b.randomized_pairs), :2] = float(world.friction)
        data = mujoco.MjData(model)
        data.qpos[list(b.arm_qpos)] = world.arm_qpos
        for k, slot in enumerate(b.slots):
            if slot.how == FREE:
                data.qpos[slot.qpos_adr : slot.qpos_adr + 3] = world.object_pos[k]
                data.qpos[slot.qpos_adr + 3 : slot.qpos_adr + 7] = world.object_quat[k]
            elif slot.how == MOCAP:
                data.mocap_pos[slot.mocap_id] = world.object_pos[k]
                data.mocap_quat[slot.mocap_id] = world.object_quat[k]
        mujoco.mj_forward(model, data)
        return data

    def _tool_pose(self, data) -> tuple[np.ndarray, np.ndarray]:
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, data.site_xmat[self.spec.ctrl.site_id])
        return data.site_xpos[self.spec.ctrl.site_id].copy(), quat

    def _slot_poses(self, data, world) -> tuple[np.ndarray, np.ndarray]:
        pos = np.array(world.object_pos, float)
        quat = np.array(world.object_quat, float)
        for k, slot in enumerate(self.spec.bindings.slots):
            if slot.how == FREE:
                pos[k], quat[k] = data.xpos[slot.body_id], data.xquat[slot.body_id]
        return pos, quat

    def _healthy(self, data) -> bool:
        if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
            return False
        if np.any(np.abs(data.qvel) >= MAX_QVEL):
            return False
        return all(data.qpos[s.qpos_adr + 2] > MIN_OBJECT_Z for s in self.spec.bindings.slots if s.how == FREE)

    def run_episode(self, params, world: Worlds, record: bool = False):
        """Rolls out ``params`` (P,) in ``world`` (unbatched numpy fields); the result's fields
        are numpy scalars / (R,) as in ``rollout.episode.EpisodeResult``. With ``record``,
        returns (result, TickRecord of numpy arrays with a leading (T,) axis) like the compiled
        rollout's ``trace`` (T: ticks run; fewer if the world diverged)."""
        spec, model, cfg = self.spec, self.model, self.spec.ctrl
        params = np.asarray(params, float)
        data = self._initial_data(world)
        tool_pos, tool_quat = self._tool_pose(data)
        n_leaves = len(self.programs)
        bb = NativeBlackboard(tool_pos, tool_quat, spec.default_stiffness, n_leaves)
        cstate = NativeControllerState(data.qfrc_bias[:N_ARM], spec.default_stiffness, np.zeros(6))
        nullspace_target = np.asarray(world.arm_qpos, float)
        interp = self.interp
        interp.reset()
        live: set[int] = set()
        done, diverged = False, False
        status, done_tick = Status.RUNNING, -1
        totals = np.zeros(len(self.terms))
        max_force = 0.0
        default_stiffness = np.asarray(spec.default_stiffness, float)
        records = []

        for t in range(spec.ticks):
            tool_pos, _ = self._tool_pose(data)
            if done:  # the tree is no longer ticked: every leaf is idle
                root, active, started = status, [False] * n_leaves, [False] * n_leaves
            else:
                leaf_status = [
                    prog[0](bb, tool_pos, nid in live) for prog, nid in zip(self.programs, self.leaf_ids)
                ]
                result = interp.tick(lambda nid, node: leaf_status[self.leaf_position[nid]])
                root = result.status
                ticked = set(result.active_leaves)
                active = [nid in ticked for nid in self.leaf_ids]
                started = [a and nid not in live for a, nid in zip(active, self.leaf_ids)]
                live = _live_nodes(interp, result)
            # Held effects fall back to their defaults unless an active leaf sets them again.
            before = (copy.copy(data), cstate, bb.copy())
            bb.stiffness, bb.wrench, bb.spiral_on = default_stiffness, np.zeros(6), False
            for k, (_, effect) in enumerate(self.programs):
                if active[k]:
                    effect(bb, started[k], params)
            bb.leaf_ticks = [(1 if s else n + 1) if a else 0 for a, s, n in zip(active, started, bb.leaf_ticks)]

            for _ in range(spec.steps_per_tick):
                ref_pos, ref_quat = bb.reference()
                command = np.concatenate([ref_pos, ref_quat, bb.wrench, bb.stiffness])
                tau, cstate = native_impedance_control(cfg, model, data, command, nullspace_target, cstate)
                data.ctrl[:N_ARM] = tau
                mujoco.mj_step(model, data)
                bb.advance(cfg.dt)

            if not self._healthy(data):
                # Frozen at the last good state; rewards are replaced by the worst values below
                # (the compiled rollout keeps ticking a frozen world, which changes nothing).
                data, cstate, bb = before
                diverged = True
                break
            if root != Status.RUNNING and not done:
                done, done_tick = True, t
            status = root
            tool_pos, tool_quat = self._tool_pose(data)
            slot_pos, slot_quat = self._slot_poses(data, world)
            obs = NativeObservation(tool_pos, tool_quat, bb.reference()[0], slot_pos, slot_quat,
                                    cstate.wrench, root == Status.SUCCESS)
            raw = [term.raw(obs) for term in self.terms]
            totals += raw
            if record:
                records.append(TickRecord(data.qpos.copy(), tool_pos, obs.ref_pos, int(root), np.array(active), np.array(raw)))
            max_force = max(max_force, float(np.linalg.norm(cstate.wrench[:3])))

        if diverged:
            totals = np.array([term.worst_raw * spec.ticks for term in self.terms])
        success, pos_err, rot_err, depth = self._success(data, world)
        result = EpisodeResult(
            reward_totals=totals,
            success=bool(success and not diverged),
            diverged=diverged,
            bt_status=int(Status.FAILURE if diverged else status),
            bt_done_tick=done_tick,
            position_error=pos_err,
            orientation_error=rot_err,
            insertion_depth=depth,
            max_force=max_force,
        )
        if record:
            return result, TickRecord(*(np.array(f) for f in zip(*records))) if records else None
        return result

    def _success(self, data, world):
        spec = self.spec
        slot_pos, slot_quat = self._slot_poses(data, world)
        if spec.success_kind == "object_at_pose":
            d_pos = float(np.linalg.norm(slot_pos[spec.success_object, :2] - slot_pos[spec.success_target, :2]))
            d_rot = quat_angle(slot_quat[spec.success_object], slot_quat[spec.success_target])
            return d_pos < spec.position_tolerance and d_rot < spec.orientation_tolerance, d_pos, d_rot, 0.0
        tool_pos = data.site_xpos[spec.ctrl.site_id]
        hole_top = slot_pos[spec.success_target] + np.asarray(spec.hole_top_local)
        lateral = float(np.linalg.norm(tool_pos[:2] - hole_top[:2]))
        depth = float(hole_top[2] - tool_pos[2])
        inside = bool(np.all(np.abs(tool_pos[:2] - hole_top[:2]) < spec.hole_half_width))
        return inside and depth > spec.depth, lateral, 0.0, depth

    # -- batches ----------------------------------------------------------------------------

    def run_worlds(self, params, worlds: Worlds) -> RolloutOutput:
        """Rolls out (B, P) ``params`` in ``worlds`` of leading shape (B, W) or (W,) (the same
        worlds for every parameter set), one episode after another. Returns a RolloutOutput of
        numpy arrays with the compiled rollout's fields and metric names."""
        params = np.atleast_2d(np.asarray(params, float))
        worlds = jax.tree.map(np.asarray, worlds)
        if worlds.config_index.ndim == 1:
            worlds = jax.tree.map(lambda x: np.broadcast_to(x, (len(params),) + x.shape), worlds)
        b, w = worlds.config_index.shape
        if b != len(params):
            raise ValueError(f"worlds must have leading shape (W,) or ({len(params)}, W), got {worlds.config_index.shape}")
        results = [
            [self.run_episode(params[i], jax.tree.map(lambda x: x[i, j], worlds)) for j in range(w)] for i in range(b)
        ]
        res = EpisodeResult(*(np.array([[getattr(r, f) for r in row] for row in results]) for f in EpisodeResult._fields))
        return summarize(res, worlds.config_index, self.objective_matrix, self.reward_names, xp=np)
