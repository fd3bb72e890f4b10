"""One worker's call (21 rows, one process, one core): call time, time in Batch.step, the rest."""
import sys, time, os, json
sys.path.insert(0, "benchmarks")
import numpy as np, jax
from throughput import workload
from mjxskill.engine.native.rollout import NativeRollout
from mjxskill.engine.native.batched import run_batched
task_name, calls = sys.argv[1], int(sys.argv[2])
scn, task, params, worlds = workload(task_name, None, 6, None)[:4]
eng = NativeRollout(scn, task)
P = np.asarray(params); n = P.shape[0] * 7
flat_w = jax.tree.map(lambda x: np.ascontiguousarray(np.asarray(x).reshape((n,) + np.asarray(x).shape[2:])), worlds)
flat_p = np.repeat(P, 7, axis=0)
sel = np.arange(0, n, 2)
w21 = type(flat_w)(*(np.asarray(x)[sel] for x in flat_w)); p21 = flat_p[sel]
run_batched(eng, p21, w21)
out = []
for _ in range(calls):
    tm = {}; t0 = time.perf_counter(); run_batched(eng, p21, w21, timing=tm); t = time.perf_counter() - t0
    out.append(dict(call_s=t, physics_s=tm["physics_s"], rest_s=t - tm["physics_s"]))
print(json.dumps(out))
