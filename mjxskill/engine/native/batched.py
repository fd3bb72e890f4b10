"""Many native episodes on one ``mujoco.batch.Batch``: the BT ticked for all episodes at once
(``RowsTree``, the compiled tree over rows), each episode's active leaves' effects in Python,
the control steps between two ticks for all episodes at MuJoCo's speed.

The batch holds one simulation per episode, each world's contact friction as a per-simulation
model field (``Batch.expand``: no model copy per episode), and binds the fields the law reads
as (N, ...) arrays. Each control step is two calls for all episodes: the compiled impedance
law (``mjxskill.engine.native.kernels``) writes every row's torques, then ``Batch.step`` runs
``mj_step`` per row in C with the GIL released; the contact-force sensors are read as one
array. What ``mj_step`` leaves in a row is what it leaves in an ``MjData`` (MuJoCo's batch is
bit-identical to a loop over one ``MjData`` each), so the law sees what the numpy lockstep
(``mjxskill.engine.native_reference``, its reference) sees, and whole episodes equal its results
bit for bit (tests/engine/native/test_batched.py).

A row MuJoCo resets after its state went bad (``mj_step`` then only counts a warning, which a
batch does not report) is found by its clock: a reset sets ``time`` to 0, so the row falls
behind the others. A row MuJoCo raises an error in stops there. Either is a diverged episode,
contained as in the plain loop.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np
from mujoco.batch import Batch, SimulationError

from mjxskill.bt_compiled import init_rows
from mjxskill.bt_compiled.rows import tick_program
from mjxskill.ebt.nodes import Status
from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.bindings import FREE, MOCAP
from mjxskill.engine.common.health import free_object_z_addresses, healthy_state
from mjxskill.engine.common.rewards import Observation
from mjxskill.engine.common.types import EpisodeResult
from mjxskill.engine.common.worlds import world_pair_friction
from mjxskill.engine.native.controller import NativeControllerState
from mjxskill.engine.native.episode import SNAPSHOT_FIELDS, NativeEpisode, TickEnd, slot_poses
from mjxskill.engine.native.kernels import add_forces, impedance_rows, site_quats
from mjxskill.engine.native.leaves import references_rows
from mjxskill.sim.controller_config import N_ARM

# Bound before the batch's first call: a field bound later is only filled from the next call on.
BOUND = ("qpos", "qvel", "ctrl", "mocap_pos", "mocap_quat", "time", "xpos", "xquat", "site_xpos", "site_xmat",
         "cdof", "subtree_com", "qfrc_bias", "sensordata")


class BatchRow:
    """Simulation ``i`` of a batch, read as an ``MjData``: views into the bound (N, ...) fields."""

    def __init__(self, fields: dict, i: int):
        for name, array in fields.items():
            setattr(self, name, array[i])
        self.was_reset = False

    def frozen(self, snapshot: dict) -> "BatchRow":
        """A copy of this row with ``snapshot``'s fields: what a diverged episode is read from."""
        row = object.__new__(BatchRow)
        row.__dict__.update({name: np.array(value) for name, value in self.__dict__.items()})
        row.__dict__.update(snapshot)
        return row


def kinematic_chain(model: mujoco.MjModel, body: int) -> np.ndarray:
    """(7,) bool: the arm's dofs among the ancestors of ``body``'s motion, as ``mj_jac`` walks them."""
    while body and not model.body_dofnum[body]:
        body = model.body_parentid[body]
    chain = np.zeros(N_ARM, bool)
    dof = int(model.body_dofadr[body] + model.body_dofnum[body] - 1) if body else -1
    while dof >= 0:
        if dof < N_ARM:
            chain[dof] = True
        dof = int(model.dof_parentid[dof])
    return chain


def start_batch(engine, worlds, threads: int = 1) -> tuple[Batch, dict, np.ndarray]:
    """A batch of one simulation per world of ``worlds`` (leading (N,), numpy fields), each at
    its world's initial conditions with its friction, kinematics computed. Returns the batch,
    its bound fields and which worlds (N,) start from a state that is not finite: MuJoCo's
    batch would reset those to the model's initial state at once, where an ``MjData`` starts
    from it (and diverges at the first step, as the compiled engine's world does)."""
    n, b = len(worlds.config_index), engine.setup.bindings
    batch = Batch(engine.mj_model, n, nthread=threads)
    fields = {name: batch.bind(name) for name in BOUND}
    friction = batch.expand("pair_friction")
    for i in range(n):
        friction[i] = world_pair_friction(engine.base_pair_friction, b.randomized_pairs, worlds.friction[i], HOST)
    batch.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
    fields["qpos"][:, list(b.arm_qpos)] = worlds.arm_qpos
    for k, slot in enumerate(b.slots):
        if slot.how == FREE:
            fields["qpos"][:, slot.qpos_adr : slot.qpos_adr + 3] = worlds.object_pos[:, k]
            fields["qpos"][:, slot.qpos_adr + 3 : slot.qpos_adr + 7] = worlds.object_quat[:, k]
        elif slot.how == MOCAP:
            fields["mocap_pos"][:, slot.mocap_id] = worlds.object_pos[:, k]
            fields["mocap_quat"][:, slot.mocap_id] = worlds.object_quat[:, k]
    bad = ~(np.isfinite(fields["qpos"]).all(axis=1) & np.isfinite(fields["mocap_pos"]).all(axis=(1, 2))
            & np.isfinite(fields["mocap_quat"]).all(axis=(1, 2)))
    batch.forward(np.flatnonzero(~bad))
    return batch, fields, bad


def run_batched(engine, params: np.ndarray, worlds, threads: int = 1, timing: dict | None = None) -> list[EpisodeResult]:
    """Episodes of ``engine`` (a ``NativeRollout``) for params (N, P) in ``worlds`` (leading
    shape (N,), numpy fields) on one batch stepped by ``threads`` threads. Returns the N
    results in order; they do not depend on ``threads`` or on which episodes share the batch.
    ``timing``, if given, gets ``physics_s``: the seconds spent in ``Batch.step`` (benchmarks)."""
    batch, fields, bad = start_batch(engine, worlds, threads)
    # A world that starts from a non-finite state runs on its own MjData, as in the plain loop.
    episodes = [
        NativeEpisode(engine, params[i], _world(worlds, i), engine.mj_model.__copy__()) if bad[i]
        else NativeEpisode(engine, params[i], _world(worlds, i), None, data=BatchRow(fields, i))
        for i in range(len(params))
    ]
    stepper = _Stepper(engine, batch, fields, timed=timing is not None)
    z_adr = free_object_z_addresses(engine.setup.bindings)
    healthy = np.ones(len(episodes), bool)
    tree, site = RowsTree(engine, len(episodes)), engine.setup.ctrl.site_id
    for t in range(engine.setup.ticks):
        alive = [i for i, e in enumerate(episodes) if not e.diverged]
        if not alive:
            break
        # The batch rows' state at the tick's start, for all rows at once (an episode that
        # diverges during the tick is frozen at its row of it).
        frame = {name: fields[name].copy() for name in SNAPSHOT_FIELDS}
        ticking = [i for i in alive if not bad[i] and not episodes[i].done]
        ticked = tree.tick(episodes, ticking, fields["site_xpos"][ticking, site]) if ticking else {}
        for i in alive:
            episodes[i].begin_tick(None if bad[i] else _RowSnapshot(frame, i), ticked.get(i))
        rows: list[int] | np.ndarray = [i for i in alive if not bad[i]]
        ends: dict[int, TickEnd] = {}
        if rows:
            rows = np.array(rows, dtype=np.int64)
            reset = stepper.tick([episodes[i] for i in rows], rows)
            # NativeEpisode.healthy for these rows at once: MuJoCo did not reset them, and the test.
            healthy[rows] = ~reset & healthy_state(HOST, fields["qpos"][rows], fields["qvel"][rows], z_adr)
            ends = tick_ends(engine, [episodes[i] for i in rows], rows, fields, worlds)
        for i in alive:
            if bad[i]:
                episodes[i].plain_steps()
            episodes[i].end_tick(t, None if bad[i] else bool(healthy[i]), ends.get(i))
    if timing is not None:
        timing["physics_s"] = timing.get("physics_s", 0.0) + stepper.physics_s
    return [e.result() for e in episodes]


class RowsTree:
    """The behavior tree of a batch's episodes ticked for all rows at once: every leaf's status
    from the rows' blackboards (``LeafStatus.rows``), then the compiled tree's tick over the
    rows (``bt_compiled.rows``, tested against the reference interpreter), which each
    episode's own tick would give; the episodes then apply their active leaves' effects
    (``NativeEpisode.begin_tick``'s ``ticked``)."""

    def __init__(self, engine, n: int):
        self.ct = engine.compiled_tree
        self.state = init_rows(self.ct, n)
        self.statuses = [status for status, _ in engine.programs]

    def tick(self, episodes: list[NativeEpisode], rows: list[int], tool_pos: np.ndarray) -> dict[int, tuple]:
        """The tick of ``episodes[i]`` for the batch rows ``rows`` whose trees still run, given
        their tool positions (len(rows), 3): {row: (root status, active, started)}, the leaf
        flags as lists in ``engine.programs``' order."""
        memory, live = self.state.memory[rows], self.state.live[rows]
        leaf_live = live[:, self.ct.leaf_ids]
        bbs = [episodes[i].bb for i in rows]
        status = np.stack([s.rows(bbs, tool_pos, leaf_live[:, k]) for k, s in enumerate(self.statuses)], axis=-1)
        *state, root, active, started = tick_program(self.ct, memory, live, status)
        for field, new in zip(self.state, state):
            field[rows] = new
        return {i: (Status(r), a, s) for i, r, a, s in zip(rows, root.tolist(), active.tolist(), started.tolist())}


def tick_ends(engine, episodes: list[NativeEpisode], rows: np.ndarray, fields: dict, worlds) -> dict[int, TickEnd]:
    """The tool pose and raw rewards at a tick's end of ``episodes``, the batch rows ``rows``
    (m,), for all at once: {row: TickEnd}. The rewards' terms run on (m, ...) observations
    (``rewards.Observation``'s fields with a leading row axis), what each episode's
    ``observation`` holds row by row. Their values equal the episode's own to rounding: numpy's
    exp over rows may differ from ``math.exp`` on one value in the last bit, a quaternion's
    inner product over rows sums where one vector's is a dot product (tests/engine/native/
    test_batched.py finds whole episodes bit for bit equal on push and the peg)."""
    spec = engine.setup
    site = spec.ctrl.site_id
    tool_pos = fields["site_xpos"][rows, site]
    tool_quat = np.empty((len(rows), 4))
    site_quats(rows, site, fields["site_xmat"], tool_quat)
    slot_pos, slot_quat = slot_poses(spec.bindings, worlds.object_pos[rows], worlds.object_quat[rows],
                                     fields["xpos"][rows], fields["xquat"][rows])
    obs = Observation(tool_pos, tool_quat, np.stack([e.bb.reference()[0] for e in episodes]), slot_pos, slot_quat,
                      np.stack([e.cstate.wrench for e in episodes]),
                      np.array([e.root == Status.SUCCESS for e in episodes]),
                      np.array([e.tick_force[0] for e in episodes]) / spec.steps_per_tick)
    with np.errstate(all="ignore"):  # a row that diverged this tick: its values are not used
        raw = np.stack([term.raw(obs) for term in engine.terms], axis=-1) if engine.terms else np.zeros((len(rows), 0))
    return {int(i): TickEnd(tool_pos[r], tool_quat[r], raw[r]) for r, i in enumerate(rows)}


def _world(worlds, i: int):
    return type(worlds)(*(np.asarray(x)[i] for x in worlds))


class _RowSnapshot:
    """Row ``i`` of ``frame``, a copy of the batch's ``SNAPSHOT_FIELDS`` at a tick's start:
    what ``NativeEpisode`` restores a diverged episode to (as its own snapshot of the row)."""

    __slots__ = ("frame", "i")

    def __init__(self, frame: dict, i: int):
        self.frame, self.i = frame, i

    def restore(self, row: BatchRow) -> BatchRow:
        return row.frozen({name: np.array(array[self.i]) for name, array in self.frame.items()})


class _Stepper:
    """The control steps of one tick for the live rows of a batch."""

    def __init__(self, engine, batch: Batch, fields: dict, timed: bool = False):
        cfg, model = engine.setup.ctrl, engine.mj_model
        self.batch, self.fields, self.cfg, self.steps = batch, fields, cfg, engine.setup.steps_per_tick
        self.site, self.root = cfg.site_id, int(model.body_rootid[cfg.site_body_id])
        self.chain = kinematic_chain(model, cfg.site_body_id)
        self.rates = np.array([cfg.stiffness_rate * cfg.dt, cfg.wrench_rate * cfg.dt, cfg.torque_step,
                               cfg.pinv_damping, cfg.nullspace_stiffness])
        self.torque_limit = np.asarray(cfg.torque_limit, float)
        self.sensors = np.asarray(engine.setup.bindings.force_sensors, dtype=np.int64)
        self.timestep = float(model.opt.timestep)
        self.clock = 0.0  # the time of a row that has never been reset, summed as mj_step sums it
        self.timed, self.physics_s = timed, 0.0

    def tick(self, episodes: list[NativeEpisode], rows: np.ndarray) -> np.ndarray:
        """The control steps of one tick for ``rows`` (m,), the batch rows of ``episodes``.
        Returns which rows (m,) MuJoCo reset or stopped: their episodes diverged."""
        f, m, steps = self.fields, len(rows), self.steps
        ref_pos, ref_quat = references_rows([e.bb for e in episodes], steps, self.cfg.dt)  # (steps, m, 3), (steps, m, 4)
        cmd_wrench = np.stack([e.bb.wrench for e in episodes])
        cmd_stiffness = np.stack([e.bb.stiffness for e in episodes])
        nullspace_target = np.stack([e.nullspace_target for e in episodes])
        torque = np.stack([e.cstate.torque for e in episodes])
        stiffness = np.stack([e.cstate.stiffness for e in episodes])
        wrench = np.stack([e.cstate.wrench for e in episodes])
        force_sum, force_peak = np.zeros(m), np.zeros(m)
        failed = np.zeros(m, bool)
        live = rows
        for k in range(steps):
            # The law runs for every row of the tick, stepped or not: its per-row inputs are indexed
            # by position in ``rows``; a failed row's torques are never applied.
            impedance_rows(rows, self.chain, self.site, self.root, f["cdof"], f["subtree_com"], f["site_xpos"],
                           f["site_xmat"], f["qpos"], f["qvel"], f["qfrc_bias"], ref_pos[k], ref_quat[k], cmd_wrench,
                           cmd_stiffness, nullspace_target, torque, stiffness, wrench, self.torque_limit, self.rates,
                           f["ctrl"])
            start = time.perf_counter() if self.timed else 0.0
            try:  # every row: no ids to check (the same steps)
                self.batch.step(None if len(live) == self.batch.nsim else live)
            except SimulationError as error:  # those rows kept their state; they end here
                failed |= np.isin(rows, error.ids)
                live = rows[~failed]
            if self.timed:
                self.physics_s += time.perf_counter() - start
            add_forces(rows, f["sensordata"], self.sensors, force_sum, force_peak)
            self.clock += self.timestep
        reset = (f["time"][rows] != self.clock) | failed
        for r, e in enumerate(episodes):
            e.data.was_reset = bool(reset[r])
            e.cstate = NativeControllerState(torque[r], stiffness[r], wrench[r])
            e.tick_force = (float(force_sum[r]), float(force_peak[r]))
        return reset
