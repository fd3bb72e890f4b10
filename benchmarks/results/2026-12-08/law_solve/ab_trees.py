"""NOTES 48: one push or peg slice (21 rows of the training batch) run call by call in turn by two
long-lived processes, each importing mjxskill from its own tree (the commit before a change and
after), both on the same core, so that adjacent calls compare (this machine's rate moves by up
to 30 % between calls minutes apart). Each process checks nothing but times its calls; the
results of the two trees are compared to 1e-9 relative at the end.
    python benchmarks/results/2026-12-08/law_solve/ab_trees.py push 8 /work/wt-old /work/main
"""
import json, os, subprocess, sys

SERVER = r'''
import sys, time, json
import numpy as np, jax
sys.path.insert(0, "benchmarks")
from throughput import workload
import mjxskill.engine.native.batched as batched
scn, tsk, params, worlds, engine = workload(sys.argv[1], None, 6, None)
flat = jax.tree.map(lambda x: np.asarray(x).reshape((42,) + np.asarray(x).shape[2:]), worlds)
rows = np.arange(0, 42, 2)
fparams = np.repeat(params, 7, axis=0)[rows]
fworlds = type(flat)(*(np.ascontiguousarray(np.asarray(x)[rows]) for x in flat))
out = None
def call():
    global out
    timing = {}
    t0 = time.perf_counter()
    out = batched.run_batched(engine, fparams, fworlds, timing=timing)
    return time.perf_counter() - t0, timing["physics_s"]
call()
print("ready", flush=True)
for line in sys.stdin:
    if line.strip() == "go":
        wall, physics = call()
        print(json.dumps({"wall": wall, "physics": physics}), flush=True)
    else:
        print(json.dumps({"totals": np.array([r.reward_totals for r in out]).tolist()}), flush=True)
'''

task, rounds, trees = sys.argv[1], int(sys.argv[2]), sys.argv[3:5]
procs = []
for tree in trees:
    env = dict(os.environ, PYTHONPATH=tree, OMP_NUM_THREADS="1")
    p = subprocess.Popen([sys.executable, "-c", SERVER, task], cwd=tree, env=env, stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, text=True)
    procs.append(p)
for p in procs:
    assert p.stdout.readline().strip() == "ready"
print(f"{task}: trees {trees}, load {os.getloadavg()[0]:.2f}", flush=True)
walls = [[], []]
for r in range(rounds):
    order = (0, 1) if r % 2 == 0 else (1, 0)
    for i in order:
        procs[i].stdin.write("go\n"); procs[i].stdin.flush()
        got = json.loads(procs[i].stdout.readline())
        walls[i].append(got["wall"])
        print(f"round {r} {trees[i]}: wall {got['wall']:.3f} s, in Batch.step {got['physics']:.3f} s", flush=True)
totals = []
for p in procs:
    p.stdin.write("totals\n"); p.stdin.flush()
    totals.append(json.loads(p.stdout.readline())["totals"])
    p.stdin.close(); p.wait()
import numpy as np
a, b = np.array(totals[0], float), np.array(totals[1], float)
ratio = np.array(walls[1]) / np.array(walls[0])
print(f"{task}: largest relative difference of the reward totals {np.max(np.abs(a - b) / np.maximum(np.abs(a), 1e-12)):.2e}")
print(f"{task}: {trees[1]} / {trees[0]} wall, per round: median {np.median(ratio):.3f} [{ratio.min():.3f}, {ratio.max():.3f}]; "
      f"medians {np.median(walls[0]):.3f} s, {np.median(walls[1]):.3f} s; load {os.getloadavg()[0]:.2f}")
