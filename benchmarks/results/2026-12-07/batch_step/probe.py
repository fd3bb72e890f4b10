"""Where MuJoCo's step is slower inside a native call than in mujoco.rollout's replay (NOTES 44).

One worker's share of the training batch (21 of the 6 x 7 episodes, round robin), recorded by the
plain loop (episode_physics.record), then the same recorded torques stepped five ways, each timed
per control step (us), best of --runs, in turn:
  engine     the native engine's call itself (run_batched, its time in Batch.step over its steps)
  replay     mujoco.rollout, one MjData per thread, whole episodes (the limit's figure)
  rowmajor   Batch.rollout: each row's whole episode in one call (the batch's machinery, replay order)
  steps      Batch.step() per control step for all rows, the torques written before (the engine's order,
             no law), with the engine's bound fields
  persistent the same on Batch(persistent=True)
  rowmajor+noop  rowmajor with a control callback installed that does nothing (VARIANTS=name,...: a subset)
    PYTHONPATH=. python benchmarks/results/2026-12-07/batch_step/probe.py push
"""
import os, sys, time
import numpy as np, jax, mujoco, numba
sys.path.insert(0, "benchmarks")
from throughput import workload
from episode_physics import record, replay, USER_INPUTS, full_state
from mujoco.batch import Batch
from mjxskill.engine.native.batched import BOUND, run_batched

task = sys.argv[1]
runs = int(sys.argv[2]) if len(sys.argv) > 2 else 3
scn, tsk, params, worlds, engine = workload(task, None, 6, None)
sel = (slice(None), slice(None))
flat = jax.tree.map(lambda x: np.asarray(x).reshape((42,) + np.asarray(x).shape[2:]), worlds)
rows = np.arange(0, 42, 2)
fparams = np.repeat(params, 7, axis=0)[rows]
fworlds = type(flat)(*(np.ascontiguousarray(np.asarray(x)[rows]) for x in flat))
print("load before", os.getloadavg()[0], flush=True)
rec = record(engine, fparams, jax.tree.map(lambda x: x[:, None], fworlds))
n, T = rec["inputs"].shape[:2]
print(f"{task}: {n} of 21 episodes replayed, {T} steps each", flush=True)
nu = engine.mj_model.nu
INTEG = mujoco.mjtState.mjSTATE_INTEGRATION
FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
USER = getattr(mujoco.mjtState, USER_INPUTS)


def batch_at_start(persistent=False, bound=BOUND):
    b = Batch(engine.mj_model, n, nthread=1, persistent=persistent)
    fields = {name: b.bind(name) for name in bound}
    fr = b.expand("pair_friction")
    for i in range(n):
        fr[i] = rec["models"][i].pair_friction
    b.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
    for i in range(n):
        d = mujoco.MjData(rec["models"][i])
        mujoco.mj_setState(rec["models"][i], d, rec["starts"][i], FULL)
        mujoco.mj_setState(rec["models"][i], d, rec["inputs"][i, 0], USER)  # the world's mocap poses: user inputs
        mujoco.mj_getState(rec["models"][i], d, b.state[i], INTEG)
    b.forward()
    return b, fields


def final_error(b):
    err = 0.0
    for i in range(n):
        d = b.get_data(i)
        err = max(err, float(np.max(np.abs(full_state(rec["models"][i], d) - rec["finals"][i]))))
    return err


def steps(persistent):
    b, f = batch_at_start(persistent)
    ctrl, inputs, step = f["ctrl"], rec["inputs"], b.step
    t0 = time.perf_counter()
    for k in range(T):
        ctrl[:] = inputs[:, k, :nu]
        step(None)
    return time.perf_counter() - t0, final_error(b)


def rowmajor():
    b, f = batch_at_start()
    control = np.ascontiguousarray(rec["inputs"])
    out = {"qpos": np.empty((n, T, engine.mj_model.nq))}
    t0 = time.perf_counter()
    b.rollout(T, control=control, control_spec=USER.value, record=("qpos",), out=out)
    return time.perf_counter() - t0, final_error(b)


def engine_call():
    timing = {}
    run_batched(engine, fparams, fworlds, timing=timing)
    return timing["physics_s"] * n / 21, 0.0  # physics_s over all 21 rows; per step below


@numba.cfunc(numba.types.void(numba.types.int64, numba.types.int64), nopython=True)
def noop(m, d):
    return


def rowmajor_noop():
    previous = mujoco.get_mjcb_control()
    mujoco.set_mjcb_control(noop.ctypes)
    try:
        return rowmajor()
    finally:
        mujoco.set_mjcb_control(previous)


res = {}
variants = (("engine", engine_call), ("replay", lambda: replay(rec, 1, runs=1)[::2]), ("rowmajor", rowmajor),
            ("steps", lambda: steps(False)), ("persistent", lambda: steps(True)))
if os.environ.get("VARIANTS"):
    variants = [v for v in variants + (("rowmajor+noop", rowmajor_noop),) if v[0] in os.environ["VARIANTS"].split(",")]
for r in range(runs):
    for name, fn in variants:
        s, err = fn()
        res.setdefault(name, []).append((s, err))
for name, v in res.items():
    us = [1e6 * s / (n * T) for s, _ in v]
    print(f"{name:10s} us/step best {min(us):6.2f}  all {' '.join(f'{u:.2f}' for u in us)}  max final-state error {max(e for _, e in v):.1e}")
print("load after", os.getloadavg()[0])
