"""The pool's call (2 worker processes, the training batch of 6 x 7) timed --calls times, as
throughput.py's native row times it; run beside slices.py's two slices in one window (NOTES 44).
    PYTHONPATH=. python benchmarks/results/2026-12-07/batch_step/pool_call.py push 3
"""
import os, sys, time
import numpy as np
sys.path.insert(0, "benchmarks")
from throughput import workload
from mjxskill.engine.native import NativeRollout, ProcessPoolRollout

task, calls = sys.argv[1], int(sys.argv[2])
scn, tsk, params, worlds, _ = workload(task, None, 6, None)
inner = NativeRollout(scn, tsk, worlds=7)
pool = ProcessPoolRollout(inner, 2)
pool.start()
pool.run_worlds(params[:1], type(worlds)(*(x[:1] for x in worlds)))
steps = 42 * inner.setup.ticks * inner.setup.steps_per_tick
for c in range(calls):
    t0 = time.perf_counter()
    pool.run_worlds(params, worlds)
    wall = time.perf_counter() - t0
    print(f"{task} pool call {c}: wall {wall:.3f} s, {steps / wall:.0f} steps/s, load {os.getloadavg()[0]:.2f}", flush=True)
pool.close()
