"""NOTES 45: the per-step loop (the engine's stepper before the control callback, copied here) and
the control callback, call by call in one process on one slice of the training batch (this machine's
rate moves by up to 20 % between calls, so only adjacent calls compare). Results checked equal.
    PYTHONPATH=. python benchmarks/results/2026-12-07/batch_step/ab_inprocess.py push 10
"""
import contextlib, os, sys, time, types
import numpy as np, jax
sys.path.insert(0, "benchmarks")
from throughput import workload
import mjxskill.engine.native.batched as batched
from mujoco.batch import SimulationError
from mjxskill.engine.native.kernels import add_forces, impedance_rows


class PerStepStepper:
    """The stepper of 6f74b76: the law over rows between two Batch.step calls of one step each."""

    def __init__(self, engine, batch, fields, episodes, timed=False):
        cfg, model = engine.setup.ctrl, engine.mj_model
        self.batch, self.fields, self.cfg, self.steps = batch, fields, cfg, engine.setup.steps_per_tick
        self.site, self.root = cfg.site_id, int(model.body_rootid[cfg.site_body_id])
        self.chain = batched.kinematic_chain(model, cfg.site_body_id)
        self.rates = np.array([cfg.stiffness_rate * cfg.dt, cfg.wrench_rate * cfg.dt, cfg.torque_step,
                               cfg.pinv_damping, cfg.nullspace_stiffness])
        self.torque_limit = np.asarray(cfg.torque_limit, float)
        self.sensors = np.asarray(engine.setup.bindings.force_sensors, dtype=np.int64)
        self.timestep = float(model.opt.timestep)
        self.clock = 0.0
        self.timed, self.physics_s = timed, 0.0
        self.context = types.SimpleNamespace(release=lambda: None)  # run_batched releases a context

    def tick(self, episodes, rows):
        f, m, board = self.fields, len(rows), episodes.board
        ref_pos, ref_quat = board.references(rows, self.steps, self.cfg.dt)
        cmd_wrench, cmd_stiffness = board.wrench[rows], board.stiffness[rows]
        nullspace_target = episodes.nullspace_target[rows]
        torque, stiffness, wrench = episodes.torque[rows], episodes.stiffness[rows], episodes.wrench[rows]
        force_sum, force_peak = np.zeros(m), np.zeros(m)
        failed = np.zeros(m, bool)
        stepped = None if m == self.batch.nsim else rows
        chain, site, root, limit, rates = self.chain, self.site, self.root, self.torque_limit, self.rates
        cdof, com, site_xpos, site_xmat = f["cdof"], f["subtree_com"], f["site_xpos"], f["site_xmat"]
        qpos, qvel, bias, ctrl, sensordata, sensors = f["qpos"], f["qvel"], f["qfrc_bias"], f["ctrl"], f["sensordata"], self.sensors
        step, timed = self.batch.step, self.timed
        for k in range(self.steps):
            impedance_rows(rows, chain, site, root, cdof, com, site_xpos, site_xmat, qpos, qvel, bias, ref_pos[k],
                           ref_quat[k], cmd_wrench, cmd_stiffness, nullspace_target, torque, stiffness, wrench, limit,
                           rates, ctrl)
            start = time.perf_counter() if timed else 0.0
            try:
                step(stepped)
            except SimulationError as error:
                failed |= np.isin(rows, error.ids)
                stepped = rows[~failed]
            if timed:
                self.physics_s += time.perf_counter() - start
            add_forces(rows, sensordata, sensors, force_sum, force_peak)
            self.clock += self.timestep
        episodes.torque[rows], episodes.stiffness[rows], episodes.wrench[rows] = torque, stiffness, wrench
        return (f["time"][rows] != self.clock) | failed, (force_sum, force_peak)


task, rounds = sys.argv[1], int(sys.argv[2])
scn, tsk, params, worlds, engine = workload(task, None, 6, None)
flat = jax.tree.map(lambda x: np.asarray(x).reshape((42,) + np.asarray(x).shape[2:]), worlds)
rows = np.arange(0, 42, 2)
fparams = np.repeat(params, 7, axis=0)[rows]
fworlds = type(flat)(*(np.ascontiguousarray(np.asarray(x)[rows]) for x in flat))
callback_stepper, installed = batched._Stepper, batched.installed
modes = {"per-step loop": (PerStepStepper, lambda control: contextlib.nullcontext()),
         "control callback": (callback_stepper, installed)}


def call(mode):
    batched._Stepper, batched.installed = modes[mode]
    timing = {}
    t0 = time.perf_counter()
    out = batched.run_batched(engine, fparams, fworlds, timing=timing)
    return time.perf_counter() - t0, timing["physics_s"], out


for mode in modes:  # numba's caches loaded
    call(mode)
print(f"{task}: load {os.getloadavg()[0]:.2f}", flush=True)
walls = {mode: [] for mode in modes}
for r in range(rounds):
    outs = {}
    for mode in (modes if r % 2 == 0 else reversed(list(modes))):
        wall, physics, outs[mode] = call(mode)
        walls[mode].append(wall)
        print(f"round {r} {mode}: wall {wall:.3f} s, in Batch.step {physics:.3f} s", flush=True)
    a, b = outs.values()
    assert all(np.array_equal(getattr(x, f), getattr(y, f), equal_nan=True) for x, y in zip(a, b) for f in x._fields), "results differ"
ratio = np.array(walls["control callback"]) / np.array(walls["per-step loop"])
print(f"{task}: callback / per-step wall, per round: median {np.median(ratio):.3f} [{np.min(ratio):.3f}, {np.max(ratio):.3f}]; "
      f"medians {np.median(walls['per-step loop']):.3f} s, {np.median(walls['control callback']):.3f} s; load {os.getloadavg()[0]:.2f}")
