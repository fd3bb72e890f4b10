"""Same physics, two orders: every row one step per call (the engine's), or one row's 50 steps per call."""
import sys, time, numpy as np, jax
sys.path.insert(0, "benchmarks")
from throughput import workload
from mjxskill.engine.native.rollout import NativeRollout
from mjxskill.engine.native.batched import start_batch
task = sys.argv[1]
scn, tsk, params, worlds = workload(task, None, 6, None)[:4]
eng = NativeRollout(scn, tsk)
flat = jax.tree.map(lambda x: np.ascontiguousarray(np.asarray(x).reshape((42,) + np.asarray(x).shape[2:])), worlds)
sel = np.arange(0, 42, 2)
w21 = type(flat)(*(np.asarray(x)[sel] for x in flat))
batch, f, bad = start_batch(eng, w21)
rng = np.random.default_rng(0)
ctrl = rng.normal(0, 20, size=f["ctrl"].shape)
f["ctrl"][:] = ctrl
batch.step(nstep=200)  # away from rest
q0, v0, t0_ = f["qpos"].copy(), f["qvel"].copy(), f["time"].copy()
act0 = None
def restore():
    f["qpos"][:] = q0; f["qvel"][:] = v0; f["time"][:] = t0_; f["ctrl"][:] = ctrl
    batch.forward(np.arange(21))
res = {}
for rep in range(3):
    for order in ("rows per step", "steps per row"):
        restore()
        t = time.perf_counter()
        for tick in range(20):
            if order == "rows per step":
                for k in range(50):
                    batch.step(None)
            else:
                for i in range(21):
                    batch.step(np.array([i]), nstep=50)
        res.setdefault(order, []).append(time.perf_counter() - t)
        res.setdefault(order + " state", f["qpos"].copy())
print({k: [round(x, 3) for x in v] for k, v in res.items() if "state" not in k})
print("same final state:", np.array_equal(res["rows per step state"], res["steps per row state"]))
