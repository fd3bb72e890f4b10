"""Alternating A/B of the native engine alone, several calls per process: python ab_native2.py TASK OUT.json WT..."""
import json, os, subprocess, sys, time
task, out, trees = sys.argv[1], sys.argv[2], sys.argv[3:]
reps = int(os.environ.get("REPS", "2")); calls = int(os.environ.get("CALLS", "5"))
code = r'''
import sys, json, os, time
sys.path.insert(0, "benchmarks")
import numpy as np
from throughput import workload
from mjxskill.engine.native import NativeRollout, ProcessPoolRollout
scn, task, params, worlds, engine = workload(sys.argv[1], None, 6, None)
out = []
for n in (1, 2):
    inner = NativeRollout(scn, task, worlds=worlds.config_index.shape[1])
    eng = ProcessPoolRollout(inner, n) if n > 1 else inner
    if n > 1: eng.start()
    eng.run_worlds(params[:1], type(worlds)(*(x[:1] for x in worlds)))
    times = []
    for _ in range(int(sys.argv[2])):
        t0 = time.perf_counter(); eng.run_worlds(params, worlds); times.append(time.perf_counter() - t0)
    eng.close()
    steps = params.shape[0] * worlds.config_index.shape[1] * inner.control_steps_per_episode
    out.append(dict(workers=n, times=times, best=steps / min(times), median=steps / float(np.median(times)), load=os.getloadavg()[0]))
print(json.dumps(out))
'''
results = []
for rep in range(reps):
    for wt in trees:
        got = subprocess.run([sys.executable, "-c", code, task, str(calls)], cwd=wt, env=dict(os.environ, PYTHONPATH=wt),
                             capture_output=True, text=True)
        try:
            rows = json.loads(got.stdout.strip().splitlines()[-1])
        except Exception:
            print(got.stderr[-2000:]); raise
        for r in rows:
            r.update(tree=wt, rep=rep, time=time.strftime("%H:%M:%S"))
            results.append(r)
            print(wt, rep, r["workers"], f"best {r['best']:.0f} median {r['median']:.0f}", f"load {r['load']:.2f}", flush=True)
json.dump(results, open(out, "w"), indent=1)
