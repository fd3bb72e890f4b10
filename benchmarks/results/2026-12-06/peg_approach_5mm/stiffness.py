import sys, json, tempfile, numpy as np, jax
from pathlib import Path
from mjxskill import load_scenario, plan_task
from mjxskill.engine.build import build_rollout
from mjxskill.sim import asset_path
GOAL = "(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)"
SETS = {"pick_s0": [-2.296, 0.0426, 0.034], "pick_s1": [-4.631, 0.048, 0.042], "op_b": [-8.0, 0.02, 0.05]}
per = 16
def scenario(stiff):
    text = (asset_path() / "scenarios" / "peg.yaml").read_text()
    text = text.replace("scene: ../peg.xml", f"scene: {asset_path() / 'peg.xml'}")
    text = text.replace("skill_library: ../skills/library.yaml", f"skill_library: {asset_path() / 'skills' / 'library.yaml'}")
    text = text.replace("  GoToLinear.threshold: {default: 0.005}\n", f"  GoToLinear.threshold: {{default: 0.005}}\n  PegInsertion.stiffness: {{default: [{stiff}, {stiff}, 0, 50, 50, 50]}}\n")
    f = tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False); f.write(text); f.close(); return f.name
for stiff in map(float, sys.argv[1:]):
    path = scenario(stiff)
    scn = load_scenario(path); task = plan_task(scn, GOAL)
    configs = np.concatenate([np.asarray(scn.robot.start_configs), np.asarray(scn.robot.eval_configs)])
    with build_rollout(scn, task, "native", worlds=per * len(configs), episode_seconds=18.0, workers=2) as r:
        worlds = r.worlds_per_config(jax.random.PRNGKey(41), per, configs)
        out = r.run_worlds(np.array(list(SETS.values())), worlds)
    s = np.asarray(out.success).reshape(len(SETS), len(configs), per)
    known = len(scn.robot.start_configs)
    for name, row in zip(SETS, s):
        print(f"stiffness {stiff:6.0f} {name:8s} known {row[:known].mean():.3f} unseen {row[known:].mean():.3f} all {row.mean():.3f}", flush=True)
    Path(path).unlink()
