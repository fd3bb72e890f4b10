import sys, json
sys.path.insert(0, "benchmarks")
import numpy as np, jax
from peg_approach import settled_scenario, all_configs, SETS, GOAL
from mjxskill import load_scenario, plan_task
from mjxskill.engine.build import build_rollout
per = 16
scn_path = "peg"
scn = load_scenario(scn_path); task = plan_task(scn, GOAL)
configs = all_configs(scn)
params = np.array([[-2.296, 0.0426, 0.034], [-4.631, 0.048, 0.042], [-8.0, 0.02, 0.05]])
with build_rollout(scn, task, "native", worlds=per * len(configs), episode_seconds=18.0, workers=2) as r:
    worlds = r.worlds_per_config(jax.random.PRNGKey(41), per, configs)
    out = r.run_worlds(params, worlds)
succ = np.asarray(out.success).reshape(3, -1)
pos = np.asarray(worlds.object_pos)[:, 0, :2]
nominal = np.median(pos, axis=0)
off = np.linalg.norm(pos - nominal, axis=1) * 1000
np.savez("benchmarks/results/2026-12-06/peg_approach_5mm/offsets.npz", succ=succ, off=off, pos=pos)
for i, name in enumerate(["pick_s0", "pick_s1", "op_b"]):
    s = succ[i]
    print(name, "success %.3f" % s.mean(), "failed offsets mm:", np.round(np.sort(off[~s.astype(bool)]), 1))
print("offset quantiles", np.percentile(off, [50, 90, 95, 98, 99]).round(1))
