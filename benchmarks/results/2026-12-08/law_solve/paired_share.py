"""NOTES 48: the engine's share of the episodes' own physics with both sampled in the same minutes.
``throughput.py`` times the limit (the best of two replays) and the engine (the median of its
calls) minutes apart, and this machine's rate moves by up to 30 % between them. Here each round
times one replay of the batch's recorded episodes on all cores (``episode_physics.replay_unrecorded``,
Batch.rollout, sensors only) and one call of the engine (two worker processes, the training batch),
in turn, the order alternating; the share is the replay's seconds over the call's, per round.
    python benchmarks/results/2026-12-08/law_solve/paired_share.py push 8
"""
import os, sys, time
import numpy as np
sys.path.insert(0, "benchmarks")
from throughput import workload
from episode_physics import record, replay_unrecorded
from mjxskill.engine.native import NativeRollout, ProcessPoolRollout
from mjxskill.engine.native.pool import default_workers

task, rounds = sys.argv[1], int(sys.argv[2])
scn, tsk, params, worlds, engine = workload(task, None, 6, None)
recording = record(engine, params, worlds)
cores = default_workers()
assert len(recording["models"]) == recording["episodes"] == 42, "an episode diverged: the two would differ in steps"
inner = NativeRollout(scn, tsk, worlds=worlds.config_index.shape[1])
pool = ProcessPoolRollout(inner, cores)
pool.start()
pool.run_worlds(params[:1], type(worlds)(*(x[:1] for x in worlds)))
print(f"{task}: {cores} cores, load {os.getloadavg()[0]:.2f}", flush=True)
shares = []
for r in range(rounds):
    got = {}
    for what in (("replay", "engine") if r % 2 == 0 else ("engine", "replay")):
        if what == "replay":
            got[what] = replay_unrecorded(recording, cores, runs=1)[0]
        else:
            t0 = time.perf_counter()
            pool.run_worlds(params, worlds)
            got[what] = time.perf_counter() - t0
    shares.append(got["replay"] / got["engine"])
    print(f"round {r}: replay {got['replay']:.3f} s, engine {got['engine']:.3f} s, share {shares[-1]:.3f}", flush=True)
pool.close()
print(f"{task}: share per round median {np.median(shares):.3f} [{min(shares):.3f}, {max(shares):.3f}]; load {os.getloadavg()[0]:.2f}")
