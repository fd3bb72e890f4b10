import sys, time
sys.path.insert(0, "/work/main/benchmarks"); sys.path.insert(0, "/work/main")
import numpy as np, mujoco
from throughput import workload
from episode_physics import record
from mjxskill.engine.native.rollout import NativeRollout
task_name = sys.argv[1]
scn, task, params, worlds = workload(task_name, None, 6, None)[:4]
eng = NativeRollout(scn, task)
rec = record(eng, params[:2], type(worlds)(*(np.asarray(x)[:2] for x in worlds)))
m = rec["models"][0]
print("ngeom", m.ngeom, "nmesh", m.nmesh, "npair", m.npair, "nexclude", m.nexclude, "opt.cone", m.opt.cone, "jacobian", m.opt.jacobian, "solver", m.opt.solver, "iterations", m.opt.iterations, "ls", m.opt.ls_iterations, "ccd_iter", m.opt.ccd_iterations, "enableflags", m.opt.enableflags, "disableflags", m.opt.disableflags)
spec = mujoco.mjtState.mjSTATE_USER
names = [n for n in dir(mujoco.mjtTimer) if n.startswith("mjTIMER")]
tot = {}; ncon = []; nefc = []; iters = []
for e in range(len(rec["models"])):
    model = rec["models"][e]; d = mujoco.MjData(model)
    mujoco.mj_setState(model, d, rec["starts"][e], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    for k in range(rec["inputs"].shape[1]):
        mujoco.mj_setState(model, d, rec["inputs"][e, k], spec)
        mujoco.mj_step(model, d)
        ncon.append(d.ncon); nefc.append(d.nefc); iters.append(d.solver_niter[0])
    for n in names:
        t = d.timer[getattr(mujoco.mjtTimer, n)]
        tot[n] = tot.get(n, 0.0) + t.duration
step = tot["mjTIMER_STEP"]
for n in names:
    if tot[n] > 0: print(f"{n:28s} {tot[n]/step:6.3f}")
print("mean ncon", np.mean(ncon), "max", np.max(ncon), "mean nefc", np.mean(nefc), "mean solver iters", np.mean(iters))
g = [(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, i), m.geom_type[i], m.geom_contype[i], m.geom_conaffinity[i]) for i in range(m.ngeom)]
print(len(g), "geoms; collidable:", sum(1 for x in g if x[2] or x[3]))
T = {int(v): k for k, v in mujoco.mjtGeom.__members__.items()}
for p in range(m.npair):
    a, b = m.pair_geom1[p], m.pair_geom2[p]
    print(p, mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, a), T.get(int(m.geom_type[a])), "|", mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, b), T.get(int(m.geom_type[b])), "margin", m.pair_margin[p])
print("mujoco", mujoco.__version__, [n for n in dir(mujoco.mjtEnableBit)], [n for n in dir(mujoco.mjtDisableBit) if "CCD" in n.upper() or "MID" in n.upper()])
