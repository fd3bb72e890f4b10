"""One worker's slice of the training batch (21 of the 6 x 7 episodes, round robin: slice 0 or 1),
run by run_batched as a pool worker runs it, --calls times: per call its wall and CPU seconds, its seconds
in Batch.step and the rest, per control step (us). Run alone, then two at once (one per slice, as
the pool's two workers), to see what two cores at once cost the engine's call (NOTES 44).
    PYTHONPATH=. python benchmarks/results/2026-12-07/batch_step/slices.py push 0 3
"""
import os, sys, time
import numpy as np, jax
sys.path.insert(0, "benchmarks")
from throughput import workload
from mjxskill.engine.native.batched import run_batched

task, k, calls = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
scn, tsk, params, worlds, engine = workload(task, None, 6, None)
flat = jax.tree.map(lambda x: np.asarray(x).reshape((42,) + np.asarray(x).shape[2:]), worlds)
rows = np.arange(k, 42, 2)
fparams = np.repeat(params, 7, axis=0)[rows]
fworlds = type(flat)(*(np.ascontiguousarray(np.asarray(x)[rows]) for x in flat))
run_batched(engine, fparams[:1], type(fworlds)(*(x[:1] for x in fworlds)))  # numba's cache loaded
steps = len(rows) * engine.setup.ticks * engine.setup.steps_per_tick
for c in range(calls):
    timing = {}
    t0, c0 = time.perf_counter(), time.process_time()
    run_batched(engine, fparams, fworlds, timing=timing)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"{task} slice {k} call {c}: wall {wall:.3f} s, Batch.step {timing['physics_s']:.3f} s "
          f"({1e6 * timing['physics_s'] / steps:.2f} us/step), rest {wall - timing['physics_s']:.3f} s, "
          f"{steps / wall:.0f} steps/s, cpu {cpu:.3f} s, load {os.getloadavg()[0]:.2f}", flush=True)
