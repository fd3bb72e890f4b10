"""Many native episodes on one ``mujoco.batch.Batch``, their state as arrays with a row per
episode (``BatchEpisodes``): each tick, every leaf's status and the BT's tick for all rows at
once (the compiled tree's program, ``bt_compiled.rows``), the active leaves' effects over rows
(``board.RowsBoard``), then the control steps between two ticks for all episodes at MuJoCo's
speed, then the rewards over rows.

The batch holds one simulation per episode, each world's contact friction as a per-simulation
model field (``Batch.expand``: no model copy per episode), and binds the fields a tick reads as
(N, ...) arrays. A tick's control steps are one ``Batch.step(rows, nstep=steps)``: MuJoCo runs
each row's steps in turn in C with the GIL released, and the compiled impedance law runs inside
each ``mj_step`` as the control callback (``mjxskill.engine.native.callback``), on what
``mj_step`` left of the step before, as a loop of single steps would give it. What ``mj_step``
leaves in a row is what it leaves in an ``MjData`` (MuJoCo's batch is bit-identical to a loop
over one ``MjData`` each), so the law sees what the numpy lockstep
(``mjxskill.engine.native_reference``, its reference) sees, and whole episodes equal its results
bit for bit but for the last bit of a reward total (the rewards over rows here, one episode's
there: tests/engine/native/test_batched.py).

A row MuJoCo resets after its state went bad (``mj_step`` then only counts a warning, which a
batch does not report) is found by its ``userdata``, which the reset zeroes, and by its clock: a
reset sets ``time`` to 0, so the row falls behind the others. A row MuJoCo raises an error in is
back in its state before the call. Either is a diverged episode, contained as in the plain loop.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np
from mujoco.batch import Batch, SimulationError

from mjxskill.bt_compiled import init_rows
from mjxskill.bt_compiled.rows import row_tables, tick_program
from mjxskill.ebt.nodes import Status
from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.bindings import FREE, MOCAP
from mjxskill.engine.common.health import free_object_z_addresses, healthy_state
from mjxskill.engine.common.rewards import Observation
from mjxskill.engine.common.types import EpisodeResult
from mjxskill.engine.common.worlds import world_pair_friction
from mjxskill.engine.native.board import RowsBoard
from mjxskill.engine.native.episode import SNAPSHOT_FIELDS, NativeEpisode, commanded_force, episode_result, slot_poses
from mjxskill.engine.native.callback import ControlContext, control_callback, installed
from mjxskill.engine.native.kernels import site_quats
from mjxskill.sim.controller_config import N_ARM
from mjxskill.sim.model import CONTROL_USERDATA

# Bound before the batch's first call: a field bound later is only filled from the next call on.
BOUND = ("qpos", "qvel", "ctrl", "mocap_pos", "mocap_quat", "time", "xpos", "xquat", "site_xpos", "site_xmat",
         "cdof", "subtree_com", "qfrc_bias", "sensordata", "userdata")


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
    results: list = [None] * len(params)
    for i in np.flatnonzero(bad):  # a world that starts from a non-finite state: its own MjData
        results[i] = plain_episode(engine, params[i], _world(worlds, int(i)))
    rows = np.flatnonzero(~bad)
    if len(rows):
        episodes = BatchEpisodes(engine, params, worlds, fields, rows)
        stepper = _Stepper(engine, batch, fields, episodes, timed=timing is not None)
        try:
            with installed(control_callback(engine.mj_model, engine.data_offsets)):
                for t in range(engine.setup.ticks):
                    alive = rows[~episodes.diverged[rows]]
                    if not len(alive):
                        break
                    episodes.begin_tick(alive)
                    reset, force = stepper.tick(episodes, alive)
                    episodes.end_tick(t, alive, reset, force)
        finally:
            stepper.context.release()
        for i in rows:
            results[i] = episodes.result(int(i))
        if timing is not None:
            timing["physics_s"] = timing.get("physics_s", 0.0) + stepper.physics_s
    elif timing is not None:
        timing["physics_s"] = timing.get("physics_s", 0.0)
    return results


def plain_episode(engine, params: np.ndarray, world) -> EpisodeResult:
    """One episode on its own ``MjData`` (a private model: the world's friction), stepped by
    the plain loop, with the reference interpreter."""
    episode = NativeEpisode(engine, params, world, engine.mj_model.__copy__())
    episode.run()
    return episode.result()


class BatchEpisodes:
    """The episodes of a batch, one per row, as arrays: their blackboards (``RowsBoard``), the
    controller's rate-limited state, the BT's state machines, and what ``NativeEpisode`` keeps
    of an episode (its status, done tick, rewards, forces), advanced a tick at a time for the
    alive rows at once as ``NativeEpisode.begin_tick`` and ``end_tick`` advance one episode
    (tests/engine/native/test_batched.py: whole episodes equal the numpy lockstep's).
    A row that diverges ends there: its simulation state at the tick's start (``SNAPSHOT_FIELDS``)
    is kept for its result, as an episode restores it, and nothing of it is advanced again."""

    def __init__(self, engine, params: np.ndarray, worlds, fields: dict, rows: np.ndarray):
        n, spec = len(params), engine.setup
        self.engine, self.worlds, self.fields, self.spec = engine, worlds, fields, spec
        self.site = spec.ctrl.site_id
        # ``rows``: the batch rows it runs (the others, never stepped, hold placeholders)
        tool_pos, tool_quat = np.zeros((n, 3)), np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        tool_pos[rows], tool_quat[rows] = self.tool_pose(rows)
        self.board = RowsBoard(tool_pos, tool_quat, spec.default_stiffness, len(engine.programs), params)
        self.statuses, self.effects = [s for s, _ in engine.programs], [e for _, e in engine.programs]
        self.ct = engine.compiled_tree
        self.tables = row_tables(self.ct)
        self.bt = init_rows(self.ct, n)
        # the controller's rate-limited state (NativeControllerState's fields) and its nullspace target
        self.torque = np.array(fields["qfrc_bias"][:, :N_ARM], float)
        self.stiffness, self.wrench = np.tile(np.asarray(spec.default_stiffness, float), (n, 1)), np.zeros((n, 6))
        self.nullspace_target = np.array(worlds.arm_qpos, float)
        self.done, self.diverged = np.zeros(n, bool), np.zeros(n, bool)
        self.status, self.root = np.full(n, int(Status.RUNNING)), np.full(n, int(Status.RUNNING))
        self.done_tick = np.full(n, -1)
        self.totals = np.zeros((n, len(engine.terms)))
        self.peak_commanded_force = np.zeros(n)
        self.force_sum, self.force_peak = np.zeros(n), np.zeros(n)
        self.z_adr = free_object_z_addresses(spec.bindings)
        self.frame: dict = {}
        self.frozen: dict[int, dict] = {}  # row -> its SNAPSHOT_FIELDS at the tick it diverged in

    def tool_pose(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tool's position (m, 3) and orientation (m, 4) in ``rows`` now."""
        quat = np.empty((len(rows), 4))
        site_quats(rows, self.site, self.fields["site_xmat"], quat)
        return self.fields["site_xpos"][rows, self.site], quat

    def begin_tick(self, alive: np.ndarray) -> None:
        """The BT tick of the alive rows whose trees still run (every leaf's status over rows,
        the compiled tree's tick, ``bt_compiled.rows``) and the tick's effects."""
        self.frame = {name: self.fields[name].copy() for name in SNAPSHOT_FIELDS}  # for a row that diverges
        ticking = alive[~self.done[alive]]
        self.root[alive] = self.status[alive]  # a finished tree's root stays as it ended
        n_leaves = len(self.effects)
        active, started = np.zeros((len(ticking), n_leaves), bool), np.zeros((len(ticking), n_leaves), bool)
        if len(ticking):
            memory, live = self.bt.memory[ticking], self.bt.live[ticking]
            leaf_live = live[:, self.ct.leaf_ids]
            tool_pos = self.fields["site_xpos"][ticking, self.site]
            leaf_status = np.stack([s.rows(self.board, ticking, tool_pos, leaf_live[:, k])
                                    for k, s in enumerate(self.statuses)], axis=-1)
            *state, root, active, started = tick_program(self.tables, memory, live, leaf_status)
            for field, new in zip(self.bt, state):
                field[ticking] = new
            self.root[ticking] = root
        self.board.apply_effects(alive, ticking, active, started, self.effects)

    def end_tick(self, t: int, alive: np.ndarray, reset: np.ndarray, force: tuple[np.ndarray, np.ndarray]) -> None:
        """The alive rows after the tick's control steps: ``reset`` (m,) the rows MuJoCo reset or
        stopped, ``force`` this tick's contact force sum and peak (m,) each. A row whose state
        is not healthy has diverged; the others' status, forces and rewards advance."""
        f = self.fields
        healthy = ~reset & healthy_state(HOST, f["qpos"][alive], f["qvel"][alive], self.z_adr)
        for r in alive[~healthy]:
            self.diverged[r] = True
            self.frozen[int(r)] = {name: np.array(array[r]) for name, array in self.frame.items()}
        ok, force_sum, force_peak = alive[healthy], force[0][healthy], force[1][healthy]
        root = self.root[ok]
        finished = ok[(root != int(Status.RUNNING)) & ~self.done[ok]]
        self.done[finished], self.done_tick[finished] = True, t
        self.status[ok] = root
        self.force_sum[ok] += force_sum
        self.force_peak[ok] = np.maximum(self.force_peak[ok], force_peak)
        self.totals[ok] += self.rewards(ok, force_sum)
        self.peak_commanded_force[ok] = np.maximum(self.peak_commanded_force[ok], commanded_force(self.wrench[ok]))

    def rewards(self, rows: np.ndarray, force_sum: np.ndarray) -> np.ndarray:
        """The raw rewards (m, R) of ``rows`` at the tick's end: the terms over (m, ...)
        observations, what each episode's ``observation`` holds row by row."""
        engine, f = self.engine, self.fields
        tool_pos, tool_quat = self.tool_pose(rows)
        slot_pos, slot_quat = slot_poses(self.spec.bindings, self.worlds.object_pos[rows], self.worlds.object_quat[rows],
                                         f["xpos"][rows], f["xquat"][rows])
        if not engine.terms:
            return np.zeros((len(rows), 0))
        obs = Observation(tool_pos, tool_quat, self.board.end_pos[rows], slot_pos, slot_quat, self.wrench[rows],
                          self.root[rows] == int(Status.SUCCESS), force_sum / self.spec.steps_per_tick)
        return np.stack([term.raw(obs) for term in engine.terms], axis=-1)

    def result(self, r: int) -> EpisodeResult:
        """Row r's episode result (``NativeEpisode.result``'s)."""
        diverged = bool(self.diverged[r])
        state = self.frozen[r] if diverged else {name: self.fields[name][r] for name in SNAPSHOT_FIELDS}
        slot_pos, slot_quat = slot_poses(self.spec.bindings, self.worlds.object_pos[r], self.worlds.object_quat[r],
                                         state["xpos"], state["xquat"])
        return episode_result(self.engine, self.totals[r].copy(), diverged, int(self.status[r]), int(self.done_tick[r]),
                              np.array(state["site_xpos"][self.site]), slot_pos, slot_quat,
                              float(self.peak_commanded_force[r]), float(self.force_peak[r]), float(self.force_sum[r]))


def _world(worlds, i: int):
    return type(worlds)(*(np.asarray(x)[i] for x in worlds))


class _Stepper:
    """The control steps of one tick for the live rows of a batch: one ``Batch.step`` of the
    tick's steps, the law run inside each ``mj_step`` by the control callback
    (``mjxskill.engine.native.callback``) on the episodes' rate-limited state."""

    def __init__(self, engine, batch: Batch, fields: dict, episodes: BatchEpisodes, timed: bool = False):
        cfg, model = engine.setup.ctrl, engine.mj_model
        self.batch, self.fields, self.cfg, self.steps = batch, fields, cfg, engine.setup.steps_per_tick
        self.context = ControlContext(engine.data_offsets, self.steps, cfg, kinematic_chain(model, cfg.site_body_id),
                                      int(model.body_rootid[cfg.site_body_id]), engine.setup.bindings.force_sensors,
                                      episodes.torque, episodes.stiffness, episodes.wrench, episodes.nullspace_target)
        self.context.bind(fields["userdata"], fields)
        self.timestep = float(model.opt.timestep)
        self.clock = 0.0  # the time of a row that has never been reset, summed as mj_step sums it
        self.timed, self.physics_s = timed, 0.0

    def tick(self, episodes: BatchEpisodes, rows: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """The control steps of one tick for ``rows`` (m,) of ``episodes``. Returns which rows (m,)
        MuJoCo reset or stopped (their episodes diverged) and the tick's contact force sum and
        peak per row."""
        board = episodes.board
        ref_pos, ref_quat = board.references(rows, self.steps, self.cfg.dt)  # (steps, m, 3), (steps, m, 4)
        self.context.begin_tick(rows, ref_pos, ref_quat, board.wrench[rows], board.stiffness[rows])
        failed = np.zeros(len(rows), bool)
        start = time.perf_counter() if self.timed else 0.0
        try:  # all of the batch's rows as None (no ids to check)
            self.batch.step(None if len(rows) == self.batch.nsim else rows, nstep=self.steps)
        except SimulationError as error:  # those rows are back in their state before the call; they end here
            failed = np.isin(rows, error.ids)
        if self.timed:
            self.physics_s += time.perf_counter() - start
        for _ in range(self.steps):
            self.clock += self.timestep
        force = self.context.end_tick(rows, self.fields["sensordata"])
        # MuJoCo's reset zeroes a row's userdata (the callback then leaves it) and restarts its clock
        reset = (self.fields["userdata"][rows, -CONTROL_USERDATA] == 0) | (self.fields["time"][rows] != self.clock)
        return reset | failed, force
