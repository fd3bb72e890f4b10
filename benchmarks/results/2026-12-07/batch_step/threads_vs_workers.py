"""Both cores two ways on the training batch (NOTES 47): the pool's two worker processes (21 rows
each) and one process whose batch steps on two threads (42 rows, the tick's Python once), call by
call in turn, --rounds rounds; results asserted equal.
    PYTHONPATH=. python benchmarks/results/2026-12-07/batch_step/threads_vs_workers.py push 4
"""
import os, sys, time
import numpy as np
sys.path.insert(0, "benchmarks")
from throughput import workload
from mjxskill.engine.native import NativeRollout, ProcessPoolRollout

task, rounds = sys.argv[1], int(sys.argv[2])
scn, tsk, params, worlds, _ = workload(task, None, 6, None)
threaded = NativeRollout(scn, tsk, worlds=7)
threaded.threads = 2
pool = ProcessPoolRollout(NativeRollout(scn, tsk, worlds=7), 2)
pool.start()
engines = {"two workers": pool, "one process, two threads": threaded}
for engine in engines.values():
    engine.run_worlds(params[:1], type(worlds)(*(x[:1] for x in worlds)))
steps = 42 * threaded.setup.ticks * threaded.setup.steps_per_tick
print(f"{task}: load {os.getloadavg()[0]:.2f}", flush=True)
rates = {name: [] for name in engines}
for r in range(rounds):
    outs = []
    for name in (engines if r % 2 == 0 else reversed(list(engines))):
        t0 = time.perf_counter()
        outs.append(engines[name].run_worlds(params, worlds))
        rates[name].append(steps / (time.perf_counter() - t0))
        print(f"round {r} {name}: {rates[name][-1]:.0f} steps/s", flush=True)
    assert all(np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
               for a, b in zip(outs[0].objectives, outs[1].objectives))
pool.close()
for name, v in rates.items():
    print(f"{task} {name}: median {np.median(v):.0f} steps/s (calls {min(v):.0f}-{max(v):.0f}); load {os.getloadavg()[0]:.2f}")
