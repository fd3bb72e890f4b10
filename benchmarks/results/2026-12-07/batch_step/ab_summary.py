"""Medians of ab_callback.sh's output: python ab_summary.py FILE..."""
import re, sys
import numpy as np
for path in sys.argv[1:]:
    cur, d = None, {}
    for line in open(path):
        if line.startswith("=="):
            cur = "old (per-step loop)" if "wt-old" in line else "new (control callback)"
            continue
        m = re.search(r"(\w+) slice.*wall ([\d.]+) s, Batch.step ([\d.]+) s.*rest ([\d.]+)", line)
        if m:
            d.setdefault((m.group(1), cur), []).append(tuple(map(float, m.groups()[1:])))
    for (task, k), v in d.items():
        a = np.array(v)
        print(f"{path.split('/')[-1]}: {task} {k}: {len(a)} calls, wall median {np.median(a[:, 0]):.3f} s (min {a[:, 0].min():.3f}), "
              f"Batch.step median {np.median(a[:, 1]):.3f} s, rest median {np.median(a[:, 2]):.3f} s")
