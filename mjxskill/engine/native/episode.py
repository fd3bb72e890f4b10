"""One native episode on its own ``MjData`` as state that advances tick by tick: the plain loop's
(``NativeRollout.run_episode`` and ``trace``, a world that starts from a non-finite state) and
the numpy lockstep's (``mjxskill.engine.native_reference``), what the batch's rows
(``mjxskill.engine.native.batched``) are checked against.

Per BT tick (``begin_tick``): every leaf's status in Python (``mjxskill.engine.native.leaves``),
one tick of the reference interpreter, the active leaves' effects on the blackboard. Then
``steps_per_tick`` control steps, either ``plain_steps`` here (a user's Python loop: the numpy
controller and ``mujoco.mj_step`` one step at a time, the baseline the benchmarks measure
against) or in the numpy lockstep. Then ``end_tick``: the divergence check and the tick's rewards.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import mujoco
import numpy as np

from mjxskill.ebt.interpreter import Interpreter
from mjxskill.ebt.nodes import Status
from mjxskill.engine.native.controller import NativeControllerState, native_impedance_control
from mjxskill.engine.native.blackboard import NativeBlackboard
from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.bindings import FREE, MOCAP
from mjxskill.engine.common.rewards import Observation
from mjxskill.engine.common.success import success
from mjxskill.engine.common.worlds import world_pair_friction
from mjxskill.engine.common.health import free_object_z_addresses, healthy_state
from mjxskill.engine.common.types import EpisodeResult, TickRecord
from mjxskill.sim.controller_config import N_ARM


_RESET_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)


def initial_data(engine, model: mujoco.MjModel, world) -> mujoco.MjData:
    """Native data at ``world``'s initial conditions, kinematics computed; ``model`` gets the
    world's friction on the randomized contact pairs."""
    b = engine.setup.bindings
    model.pair_friction[:] = world_pair_friction(engine.base_pair_friction, b.randomized_pairs, world.friction, HOST)
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


def data_was_reset(data: mujoco.MjData) -> bool:
    """Whether MuJoCo reset ``data`` to the model's initial state after its state or
    accelerations went bad (it only counts a warning)."""
    return any(data.warning[w].number for w in _RESET_WARNINGS)


def slot_poses(bindings, object_pos, object_quat, xpos, xquat) -> tuple[np.ndarray, np.ndarray]:
    """The bound objects' poses now, (..., K, 3) and (..., K, 4): the world's object_pos and
    object_quat (..., K, ...), a free object's taken from the simulation's xpos and xquat
    (..., nbody, ...): one episode's, or a batch's rows with a leading axis on every argument."""
    pos, quat = np.array(object_pos, float), np.array(object_quat, float)
    for k, slot in enumerate(bindings.slots):
        if slot.how == FREE:
            pos[..., k, :], quat[..., k, :] = xpos[..., slot.body_id, :], xquat[..., slot.body_id, :]
    return pos, quat


def commanded_force(wrench: np.ndarray) -> np.ndarray:
    """The commanded force's magnitude of a wrench (..., 6): one episode's or rows'."""
    return np.sqrt(np.add.reduce(wrench[..., :3] * wrench[..., :3], axis=-1))


def episode_result(engine, totals, diverged: bool, status: int, done_tick: int, tool_pos, slot_pos, slot_quat,
                   peak_commanded_force: float, force_peak: float, force_sum: float) -> EpisodeResult:
    """An episode's result from what it kept (its reward totals (R,), whether it diverged, its
    root status and done tick, its forces) and its final tool position (3,) and object poses
    (K, 3), (K, 4): one ``NativeEpisode``'s or a batch row's."""
    spec = engine.setup
    if diverged:
        totals = np.array([term.worst_raw * spec.ticks for term in engine.terms])
    succeeded, pos_err, rot_err, depth = success(spec.success, tool_pos, slot_pos, slot_quat, HOST)
    return EpisodeResult(
        reward_totals=totals,
        success=bool(succeeded and not diverged),
        diverged=diverged,
        bt_status=int(Status.FAILURE if diverged else status),
        bt_done_tick=done_tick,
        position_error=pos_err,
        orientation_error=rot_err,
        insertion_depth=depth,
        peak_commanded_force=peak_commanded_force,
        # a diverged world's forces are not known: NaN, which meets no force limit
        peak_contact_force=math.nan if diverged else force_peak,
        mean_contact_force=math.nan if diverged else force_sum / (spec.ticks * spec.steps_per_tick),
    )


# What is read of an episode's data after it has ended: its state and the kinematics ``mj_step`` left.
SNAPSHOT_FIELDS = ("qpos", "qvel", "xpos", "xquat", "site_xpos", "site_xmat")


class _Snapshot:
    """An episode's ``SNAPSHOT_FIELDS`` at the start of a tick (copying the whole MjData each
    tick cost more than a tick's physics)."""

    FIELDS = SNAPSHOT_FIELDS

    def __init__(self, data: mujoco.MjData):
        self.arrays = [getattr(data, name).copy() for name in self.FIELDS]

    def restore(self, data: mujoco.MjData) -> mujoco.MjData:
        """``data`` restored to the snapshot, in place."""
        for name, array in zip(self.FIELDS, self.arrays):
            getattr(data, name)[:] = array
        return data


class NativeEpisode:
    """The state of one episode of ``engine`` (a ``NativeRollout``): ``params`` (P,) in ``world``
    (unbatched numpy fields), simulated on ``model`` (the engine's, or a private copy when
    several episodes run at once: each world has its own friction)."""

    def __init__(self, engine, params, world, model: mujoco.MjModel, record: bool = False):
        self.engine, self.world, self.model, self.record = engine, world, model, record
        spec = engine.setup
        self.params = np.asarray(params, float)
        self.data = initial_data(engine, model, world)
        tool_pos, tool_quat = self.tool_pose()
        self.n_leaves = len(engine.programs)
        self.bb = NativeBlackboard(tool_pos, tool_quat, spec.default_stiffness, self.n_leaves)
        self.cstate = NativeControllerState(self.data.qfrc_bias[:N_ARM], spec.default_stiffness, np.zeros(6))
        self.nullspace_target = np.asarray(world.arm_qpos, float)
        self.interp = Interpreter(engine.tree)
        self.live: set[int] = set()
        self.done, self.diverged = False, False
        self.status, self.done_tick = Status.RUNNING, -1
        self.totals = np.zeros(len(engine.terms))
        self.peak_commanded_force = 0.0
        # measured contact force (the tool's touch sensors): this tick's sum and peak over its
        # control steps (written by the stepping code), and the episode's
        self.tick_force = (0.0, 0.0)
        self.force_sum, self.force_peak = 0.0, 0.0
        self.default_stiffness = np.asarray(spec.default_stiffness, float)
        self.records: list[TickRecord] = []
        self.root, self.active = Status.RUNNING, [False] * self.n_leaves
        # the tick's starting state, (MjData snapshot, controller state, blackboard): set by
        # begin_tick, restored by end_tick when the tick diverged
        self._before: tuple[Any, NativeControllerState, NativeBlackboard] | None = None
        self._tool: tuple[np.ndarray, np.ndarray] | None = None  # the tool pose ``end_tick`` read, for the next ``begin_tick``

    # -- observation ------------------------------------------------------------------------
    def tool_pose(self) -> tuple[np.ndarray, np.ndarray]:
        site = self.engine.setup.ctrl.site_id
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, self.data.site_xmat[site])
        return self.data.site_xpos[site].copy(), quat

    def slot_poses(self) -> tuple[np.ndarray, np.ndarray]:
        return slot_poses(self.engine.setup.bindings, self.world.object_pos, self.world.object_quat, self.data.xpos,
                          self.data.xquat)

    def healthy(self) -> bool:
        data = self.data
        # MuJoCo resets the data to the model's initial state when its state or accelerations go
        # bad (NaN, huge) and only counts a warning: without this check such a world would carry
        # on from qpos0 where MJX's keeps its NaNs and is contained (found by the engines'
        # agreement test on a world with a NaN start posture).
        if data_was_reset(data):
            return False
        return bool(healthy_state(HOST, data.qpos, data.qvel, free_object_z_addresses(self.engine.setup.bindings)))

    # -- one tick ---------------------------------------------------------------------------
    def begin_tick(self) -> None:
        """The BT tick (the reference interpreter) and the active leaves' effects (the blackboard
        then holds this tick's commanded stiffness, wrench, motion and spiral)."""
        engine, bb = self.engine, self.bb
        # the tool pose the last ``end_tick`` read (nothing has stepped since), or read now
        tool = self._tool
        self._tool = None
        if self.done:  # the tree is no longer ticked: every leaf is idle
            root, active, started = self.status, [False] * self.n_leaves, [False] * self.n_leaves
        else:
            tool_pos = self.tool_pose()[0] if tool is None else tool[0]
            # A leaf's status is read from the state before the tick, which nothing writes during
            # it: asked for the leaves the tick reaches only, when it reaches them.
            programs, position, live = engine.programs, engine.leaf_position, self.live
            result = self.interp.tick(lambda nid, node: programs[position[nid]][0](bb, tool_pos, nid in live))
            root = result.status
            reached = set(result.active_leaves)
            active = [nid in reached for nid in engine.leaf_ids]
            started = [a and nid not in live for a, nid in zip(active, engine.leaf_ids)]
            self.live = self.interp.live  # ticked, and they and all ancestors RUNNING
        # Held effects fall back to their defaults unless an active leaf sets them again.
        self._before = (_Snapshot(self.data), self.cstate, bb.copy())
        bb.stiffness, bb.wrench, bb.spiral_on = self.default_stiffness, np.zeros(6), False
        for k, (_, effect) in enumerate(engine.programs):
            if active[k]:
                effect(bb, started[k], self.params)
        bb.leaf_ticks = [(1 if s else n + 1) if a else 0 for a, s, n in zip(active, started, bb.leaf_ticks)]
        self.root, self.active = root, active

    def plain_steps(self, on_step: Callable[[mujoco.MjData, np.ndarray], None] | None = None) -> None:
        """The tick's control steps one at a time: reference, numpy controller, ``mj_step``.
        ``on_step(data, tau)``: called after each step with the data and the joint torques the
        step applied (what a recording of the episode reads, ``mjxskill.calibration.record``)."""
        model, data, bb, cfg = self.model, self.data, self.bb, self.engine.setup.ctrl
        cstate = self.cstate
        sensors = list(self.engine.setup.bindings.force_sensors)
        force_sum = force_peak = 0.0
        for _ in range(self.engine.setup.steps_per_tick):
            ref_pos, ref_quat = bb.reference()
            command = np.concatenate([ref_pos, ref_quat, bb.wrench, bb.stiffness])
            tau, cstate = native_impedance_control(cfg, model, data, command, self.nullspace_target, cstate)
            data.ctrl[:N_ARM] = tau
            mujoco.mj_step(model, data)
            if on_step is not None:
                on_step(data, tau)
            force = float(np.sum(data.sensordata[sensors]))  # computed by mj_step: this step's contact force
            force_sum, force_peak = force_sum + force, max(force_peak, force)
            bb.advance(cfg.dt)
        self.cstate = cstate
        self.tick_force = (force_sum, force_peak)

    def end_tick(self, t: int) -> bool:
        """Divergence check and the tick's rewards; False when the episode has ended (diverged:
        frozen at the last good state, charged the worst rewards in ``result``)."""
        if not self.healthy():
            # The compiled rollout keeps ticking a frozen world, which changes nothing.
            snapshot, self.cstate, self.bb = self._before  # type: ignore[misc]  # begin_tick set it
            self.data = snapshot.restore(self.data)
            self.diverged = True
            return False
        root = self.root
        if root != Status.RUNNING and not self.done:
            self.done, self.done_tick = True, t
        self.status = root
        force_sum, force_peak = self.tick_force
        self.force_sum, self.force_peak = self.force_sum + force_sum, max(self.force_peak, force_peak)
        tool_pos, tool_quat = self.tool_pose()
        obs = self.observation(tool_pos, tool_quat)
        raw = [term.raw(obs) for term in self.engine.terms]
        self._tool = (tool_pos, tool_quat)
        self.totals += raw
        if self.record:
            self.records.append(TickRecord(self.data.qpos.copy(), self.data.mocap_pos.copy(), self.data.mocap_quat.copy(),
                                           tool_pos, obs.ref_pos, int(root),
                                           np.array(self.active), np.array(raw)))
        self.peak_commanded_force = max(self.peak_commanded_force, float(commanded_force(self.cstate.wrench)))
        return True

    def observation(self, tool_pos, tool_quat) -> Observation:
        """What the rewards see at the end of this tick, given the tool pose now."""
        slot_pos, slot_quat = self.slot_poses()
        return Observation(tool_pos, tool_quat, self.bb.reference()[0], slot_pos, slot_quat, self.cstate.wrench,
                           self.root == Status.SUCCESS, self.tick_force[0] / self.engine.setup.steps_per_tick)

    # -- the end ----------------------------------------------------------------------------
    def run(self, on_step: Callable[[mujoco.MjData, np.ndarray], None] | None = None) -> None:
        """The episode to its end in the plain loop: every tick, or until it diverges."""
        for t in range(self.engine.setup.ticks):
            self.begin_tick()
            self.plain_steps(on_step)
            if not self.end_tick(t):
                break

    def result(self) -> EpisodeResult:
        return episode_result(self.engine, self.totals, self.diverged, int(self.status), self.done_tick,
                              self.data.site_xpos[self.engine.setup.ctrl.site_id].copy(), *self.slot_poses(),
                              self.peak_commanded_force, self.force_peak, self.force_sum)

    def trace(self) -> TickRecord | None:
        """The per-tick record (leading (T,) axis; T: ticks run), when recording."""
        return TickRecord(*(np.array(f) for f in zip(*self.records))) if self.records else None
