"""NOTES 48: the native half of ``benchmarks/agreement.py`` alone (the same parameter sets, worlds
and key), run from the tree on PYTHONPATH, its per-world successes saved as JSON. The MJX half
does not change with the native law, so the committed agreement JSON's MJX rates still hold and
must hold 3 can be recomputed against the new native rates.
    PYTHONPATH=TREE python benchmarks/results/2026-12-08/law_solve/native_half.py peg OUT.json --run DIR --run DIR
"""
import json, os, sys, time
from pathlib import Path
sys.path.insert(0, "benchmarks")
import numpy as np, jax
from agreement import parameter_sets
from mjxskill import load_scenario, plan_task
from mjxskill.engine.build import build_rollout

task_name, out = sys.argv[1], Path(sys.argv[2])
runs = [Path(a) for a in sys.argv[3:] if a != "--run"]
scn = load_scenario(task_name)
task = plan_task(scn)
sets = parameter_sets(scn, task, runs)
names, params = list(sets), np.stack(list(sets.values()))
native = build_rollout(scn, task, "native", worlds=50)
worlds = jax.tree.map(lambda x: x[0], native.sample_worlds(jax.random.key(123), 1))
t0 = time.perf_counter()
result = native.run_worlds(params, worlds)
seconds = time.perf_counter() - t0
native.close()
out.write_text(json.dumps(dict(tree=os.environ.get("PYTHONPATH"), names=names, seconds=seconds, load=os.getloadavg()[0],
                               success=np.asarray(result.success).astype(int).tolist(),
                               objectives=np.asarray(result.objectives).tolist())))
print(f"{task_name}: {len(names)} sets x 50 worlds in {seconds:.0f} s")
