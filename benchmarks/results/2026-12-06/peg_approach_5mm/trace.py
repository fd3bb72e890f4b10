import sys, numpy as np, jax
from mjxskill import load_scenario, plan_task
from mjxskill.engine.build import build_rollout
d = np.load("benchmarks/results/2026-12-06/peg_approach_5mm/offsets.npz")
succ, off = d["succ"], d["off"]
which = int(sys.argv[1])  # set index 0 pick_s0
fails = np.flatnonzero((succ[which] == 0) & (off < 8))
print("near failures", [(int(i), round(float(off[i]), 1)) for i in fails])
idx = int(fails[int(sys.argv[2])])
per = 16
scn = load_scenario("peg"); task = plan_task(scn, "(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)")
configs = np.concatenate([np.asarray(scn.robot.start_configs), np.asarray(scn.robot.eval_configs)])
P = [[-2.296, 0.0426, 0.034], [-4.631, 0.048, 0.042], [-8.0, 0.02, 0.05]][which]
with build_rollout(scn, task, "native", worlds=per * len(configs), episode_seconds=18.0, workers=1) as r:
    worlds = r.worlds_per_config(jax.random.PRNGKey(41), per, configs)
    world = jax.tree.map(lambda a: np.asarray(a)[idx], worlds)
    result, record = r.trace(np.array(P), world)
hole = np.asarray(world.object_pos)[0]
tool, ref = np.asarray(record.tool_pos), np.asarray(record.ref_pos)
print(f"world {idx} config {idx // per} box at {np.round(hole * 1000, 1)} mm, success {bool(result.success)}")
step = max(1, int(scn.bt_hz / 10))
for t in range(0, len(tool), step):
    dd, dr = (tool[t, :2] - hole[:2]) * 1000, (ref[t, :2] - hole[:2]) * 1000
    print(f"{t / scn.bt_hz:5.2f} s tool-hole {np.round(dd, 1)} ({np.linalg.norm(dd):5.1f}) ref-hole ({np.linalg.norm(dr):5.1f}) tool z {tool[t, 2] * 1000:6.1f} ref z {ref[t, 2] * 1000:6.1f}")
