import json, sys, numpy as np
import os
HERE = os.path.dirname(os.path.abspath(__file__))
from scipy.stats import mannwhitneyu
def load(files): return [json.loads(l) for f in files for l in open(f)]
inferred = load([HERE + "/inferred_a.jsonl", HERE + "/inferred_b.jsonl", HERE + "/inferred_c.jsonl"])
given = load([HERE + "/given_ref.jsonl"])
probs = ["ZDT2 (d=6)", "CarSideImpact", "DTLZ2 (d=6, m=4)", "ZDT3 (d=6), noisy"]
def med(rs, k): return f"{np.median([r[k] for r in rs]):.4g} ({len(rs)})" if rs else "-"
def p(a, b, k):
    if len(a) < 2 or len(b) < 2: return "-"
    return f"{mannwhitneyu([r[k] for r in a], [r[k] for r in b], alternative='two-sided', method='exact').pvalue:.3g}"
print("| problem | budget | ours, reference given | ours, reference inferred | qLogNEHVI (reference given) | p, ours given vs qLogNEHVI |")
print("| --- | --- | ---: | ---: | ---: | ---: |")
for pr in probs:
    g = sorted([r for r in given if r["problem"] == pr], key=lambda r: r["seed"])
    i = sorted([r for r in inferred if r["problem"] == pr and r["column"] == "mjxskill.gp"], key=lambda r: r["seed"])
    q = sorted([r for r in inferred if r["problem"] == pr and r["column"] == "qLogNEHVI"], key=lambda r: r["seed"])
    for k, label in (("hv_half", "50 % (46 points)"), ("hv", "100 % (86)")):
        print(f"| {pr} | {label} | {med(g, k)} | {med(i, k)} | {med(q, k)} | {p(g, q, k)} |")
