import sys, json, numpy as np, jax
from mjxskill import load_scenario, plan_task
from mjxskill.engine.build import build_rollout
GOAL = "(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)"
SETS = {"pick_s0": [-2.296, 0.0426, 0.0340], "pick_s1": [-4.631, 0.048, 0.042], "op_b": [-8.0, 0.02, 0.05],
        "firm_a": [-9.42, 0.07, 0.053], "firm_b": [-10.0, 0.07, 0.038], "mid_c": [-4.88, 0.058, 0.051],
        "opb_gentle": [-2.3, 0.02, 0.05], "pick_fast": [-2.3, 0.043, 0.05]}
per = int(sys.argv[1])
scn = load_scenario("peg"); task = plan_task(scn, GOAL)
configs = np.concatenate([np.asarray(scn.robot.start_configs), np.asarray(scn.robot.eval_configs)])
params = np.array(list(SETS.values()))
with build_rollout(scn, task, "native", worlds=per * len(configs), episode_seconds=18.0, workers=2) as r:
    worlds = r.worlds_per_config(jax.random.PRNGKey(31), per, configs)
    out = r.run_worlds(params, worlds)
s = np.asarray(out.success).reshape(len(params), len(configs), per).mean(2)
known = len(scn.robot.start_configs)
doc = {}
for name, row in zip(SETS, s):
    print(f"{name:10s} {SETS[name]} known {row[:known].mean():.3f} unseen {row[known:].mean():.3f} |", " ".join(f"{x*100:3.0f}" for x in row), flush=True)
    doc[name] = row.tolist()
json.dump(doc, open(f"benchmarks/results/2026-12-06/peg_approach_5mm/sets_{per}.json", "w"))
