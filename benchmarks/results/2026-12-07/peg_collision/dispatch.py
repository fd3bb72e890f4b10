import sys, time
import os; sys.path.insert(0, os.getcwd() + "/benchmarks"); sys.path.insert(0, os.getcwd())
import numpy as np, jax
from throughput import workload
from mjxskill.engine.native.rollout import NativeRollout
from mjxskill.engine.native.batched import start_batch, _Stepper, kinematic_chain
from mjxskill.engine.native.kernels import impedance_rows, add_forces
scn, task, params, worlds = workload("push", None, 6, None)[:4]
eng = NativeRollout(scn, task)
flat_w = jax.tree.map(lambda x: np.ascontiguousarray(np.asarray(x).reshape((42,) + np.asarray(x).shape[2:])), worlds)
batch, f, bad = start_batch(eng, flat_w)
st = _Stepper(eng, batch, f)
for m in (1, 21, 42):
    rows = np.arange(m)
    ref_pos = f["site_xpos"][rows, st.site].copy(); ref_quat = np.tile([0, 1, 0, 0.0], (m, 1))
    z6 = np.zeros((m, 6)); k6 = np.full((m, 6), 400.0); ns = f["qpos"][rows, :7].copy(); tq = np.zeros((m, 7))
    args = (rows, st.chain, st.site, st.root, f["cdof"], f["subtree_com"], f["site_xpos"], f["site_xmat"], f["qpos"], f["qvel"], f["qfrc_bias"], ref_pos, ref_quat, z6, k6, ns, tq, k6.copy(), z6.copy(), st.torque_limit, st.rates, f["ctrl"])
    impedance_rows(*args)
    n = 3000; t0 = time.perf_counter()
    for _ in range(n): impedance_rows(*args)
    t_imp = (time.perf_counter() - t0) / n * 1e6
    fs, fp = np.zeros(m), np.zeros(m)
    t0 = time.perf_counter()
    for _ in range(n): add_forces(rows, f["sensordata"], st.sensors, fs, fp)
    t_add = (time.perf_counter() - t0) / n * 1e6
    t0 = time.perf_counter()
    for _ in range(300): batch.step(None)
    t_step = (time.perf_counter() - t0) / 300 * 1e6
    print(f"m={m}: impedance_rows {t_imp:.1f} us, add_forces {t_add:.1f} us, batch.step(all 42) {t_step:.0f} us")
