"""The limit's replay two ways on the training batch's episodes (NOTES 46): mujoco.rollout (records
every step's full state and sensors: episode_physics.replay) and Batch.rollout recording only the
sensors (episode_physics.replay_unrecorded), on 1 and 2 threads, alternately, best of each.
    PYTHONPATH=. python benchmarks/results/2026-12-07/batch_step/limit_replays.py push 3
"""
import os, sys
sys.path.insert(0, "benchmarks")
import episode_physics as ep
from throughput import workload

task, rounds = sys.argv[1], int(sys.argv[2])
_, _, params, worlds, engine = workload(task, None, 6, None)
rec = ep.record(engine, params, worlds)
n, nstep = rec["inputs"].shape[:2]
print(f"{task}: {n} episodes of {nstep} steps; load {os.getloadavg()[0]:.2f}", flush=True)
best = {}
for r in range(rounds):
    for threads in (1, 2):
        for name, fn in (("mujoco.rollout", ep.replay), ("Batch.rollout", ep.replay_unrecorded)):
            s, episodes, error = fn(rec, threads, runs=1)
            rate = episodes * nstep / s
            best[(name, threads)] = max(best.get((name, threads), 0.0), rate)
            print(f"round {r} {name} {threads} thread(s): {rate:.0f} steps/s, final state error {error:.1e}", flush=True)
for threads in (1, 2):
    a, b = best[("mujoco.rollout", threads)], best[("Batch.rollout", threads)]
    print(f"{task}, {threads} thread(s), best: mujoco.rollout {a:.0f}, Batch.rollout {b:.0f} steps/s ({b / a:.3f} x); load {os.getloadavg()[0]:.2f}")
