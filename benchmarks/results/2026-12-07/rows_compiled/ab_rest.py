"""Alternating A/B of one worker's call split into physics and the rest: python ab_rest.py TASK OUT.json WT..."""
import json, os, subprocess, sys, time
task, out, trees = sys.argv[1], sys.argv[2], sys.argv[3:]
reps, calls = int(os.environ.get("REPS", "4")), int(os.environ.get("CALLS", "4"))
script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "rest21.py")
results = []
for rep in range(reps):
    for wt in trees:
        got = subprocess.run(["taskset", "-c", "0", sys.executable, script, task, str(calls)], cwd=wt,
                             env=dict(os.environ, PYTHONPATH=wt, OMP_NUM_THREADS="1"), capture_output=True, text=True)
        rows = json.loads(got.stdout.strip().splitlines()[-1])
        rest = sorted(r["rest_s"] for r in rows); phys = sorted(r["physics_s"] for r in rows)
        results.append(dict(tree=wt, rep=rep, calls=rows, load=os.getloadavg()[0], time=time.strftime("%H:%M:%S")))
        print(wt, rep, f"rest median {rest[len(rest)//2]*1e3:.0f} ms min {rest[0]*1e3:.0f}  physics median {phys[len(phys)//2]:.3f} s",
              f"share {phys[len(phys)//2]/(phys[len(phys)//2]+rest[len(rest)//2]):.3f} load {os.getloadavg()[0]:.2f}", flush=True)
json.dump(results, open(out, "w"), indent=1)
