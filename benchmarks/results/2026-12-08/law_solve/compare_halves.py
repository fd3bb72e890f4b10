"""NOTES 48: the native halves before and after (native_half.py) and the committed MJX rates
(benchmarks/results/2026-12-07/agreement-TASK.json): per set the rates, and must hold 3 recomputed.
    python benchmarks/results/2026-12-08/law_solve/compare_halves.py push"""
import json, sys
import numpy as np
task = sys.argv[1]
here = "benchmarks/results/2026-12-08/law_solve"
old, new = (json.load(open(f"{here}/native-{task}-{t}.json")) for t in ("wt-old", "main"))
agreement = json.load(open(f"benchmarks/results/2026-12-07/agreement-{task}.json"))
assert old["names"] == new["names"] == [s["name"] for s in agreement["sets"]]
a, b = np.array(old["success"]), np.array(new["success"])
worst = 0.0
for k, s in enumerate(agreement["sets"]):
    diff = abs(s["mjx_success_rate"] - b[k].mean())
    worst = max(worst, diff)
    print(f"{s['name']:<40} native before {a[k].mean():.2f} (committed {s['native_success_rate']:.2f}), after {b[k].mean():.2f}, "
          f"worlds that changed {int((a[k] != b[k]).sum())}; MJX {s['mjx_success_rate']:.2f}, |MJX - after| {diff:.2f}")
print(f"{task}: worlds whose outcome the law's change moved: {int((a != b).sum())} of {a.size}; "
      f"largest |MJX - native| now {worst:.2f} (committed: {agreement['max_rate_difference']:.2f})")
