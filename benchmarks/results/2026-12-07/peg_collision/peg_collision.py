"""Collision variants of the round peg on the states its episodes visit: mj_forward's time and the
contacts each variant finds against the model as it is."""
import sys, time, copy
sys.path.insert(0, "/work/main/benchmarks"); sys.path.insert(0, "/work/main")
import numpy as np, mujoco
from throughput import workload
from mjxskill.engine.native.rollout import NativeRollout
scn, task, params, worlds = workload("peg", None, 6, None)[:4]
eng = NativeRollout(scn, task)
import jax
from mjxskill.engine.native.episode import initial_data
FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
states, models = [], []
for i in range(3):
    for j in (0, 3):
        world = jax.tree.map(lambda x: np.asarray(x)[i, j], worlds)
        model = copy.copy(eng.mj_model); initial_data(eng, model, world)
        rows = []
        def rec(d, tau, rows=rows, model=model):
            if len(rows) < 100000:
                s = np.empty(mujoco.mj_stateSize(model, FULL)); mujoco.mj_getState(model, d, s, FULL); rows.append(s)
        eng.run_episode(params[i], world, on_step=rec)
        states += rows[::15]; models += [model] * len(rows[::15])
print(len(states), "states")
def variant(model, **kw):
    m = copy.copy(model)
    for k, v in kw.items():
        if k == "disable": m.opt.disableflags |= v
        else: setattr(m.opt, k, v)
    return m
VARIANTS = {"as is": {}, "ccd_iterations=10": dict(ccd_iterations=10), "ccd_iterations=20": dict(ccd_iterations=20),
            "ccd_tolerance=1e-4": dict(ccd_tolerance=1e-4), "no multiccd": dict(disable=int(mujoco.mjtDisableBit.mjDSBL_MULTICCD)),
            "no nativeccd": dict(disable=int(mujoco.mjtDisableBit.mjDSBL_NATIVECCD))}
base_contacts = None
res = {}
for name, kw in VARIANTS.items():
    cache = {}
    ts, cons = [], []
    for s, model in zip(states, models):
        key = id(model)
        if key not in cache: cache[key] = (variant(model, **kw), None)
        m = cache[key][0]; d = mujoco.MjData(m)
        mujoco.mj_setState(m, d, s, FULL)
        mujoco.mj_forward(m, d)
        t0 = time.perf_counter()
        for _ in range(5): mujoco.mj_forward(m, d)
        ts.append((time.perf_counter() - t0) / 5)
        cons.append(sorted((int(c.geom1), int(c.geom2), round(float(c.dist), 6)) for c in d.contact[: d.ncon]) if d.ncon else [])
        cons[-1] = (d.ncon, float(min([c.dist for c in d.contact[: d.ncon]], default=0.0)), d.qacc.copy())
    res[name] = (np.sum(ts), cons)
base_t, base_c = res["as is"]
for name, (t, cons) in res.items():
    same_n = np.mean([a[0] == b[0] for a, b in zip(cons, base_c)])
    dd = np.max([abs(a[1] - b[1]) for a, b in zip(cons, base_c)])
    dq = np.median([np.linalg.norm(a[2] - b[2]) / (1 + np.linalg.norm(b[2])) for a, b in zip(cons, base_c)])
    dqmax = np.max([np.linalg.norm(a[2] - b[2]) / (1 + np.linalg.norm(b[2])) for a, b in zip(cons, base_c)])
    print(f"{name:22s} time {t / base_t:5.3f}x  same contact count {same_n:.3f}  max |deepest depth diff| {dd:.2e} m  qacc rel diff median {dq:.1e} max {dqmax:.1e}")
