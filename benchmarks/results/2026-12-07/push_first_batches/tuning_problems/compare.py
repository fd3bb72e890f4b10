"""The tuning problems under prior=dim_scaled with pending=draws against today's defaults,
paired seed by seed (benchmarks/NOTES.md section 25). The files: ``python
benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 1 --first-seed S [--option
prior=dim_scaled --option pending=draws] --save FILE`` for S in 0-9 (the reference inferred
from the warm-up, as every robot run's). Run: ``python compare.py defaults.jsonl
dim_scaled_draws.jsonl`` in this folder.
"""
import json, collections, sys, numpy as np
from scipy.stats import wilcoxon
def load(f):
    d=collections.defaultdict(dict)
    for l in open(f):
        r=json.loads(l); d[r['problem']][r['seed']]=r
    return d
base=load(sys.argv[1]); var=load(sys.argv[2])
print('| problem | seeds | at 50 %: base, candidate (ahead/behind, p) | at 100 %: base, candidate (ahead/behind, p) |')
for p in base:
    seeds=sorted(set(base[p])&set(var[p]))
    cells=[]
    for key in ('hv_half','hv'):
        b=np.array([base[p][s][key] for s in seeds]); v=np.array([var[p][s][key] for s in seeds]); d=v-b
        pv=wilcoxon(d).pvalue if np.any(d!=0) else 1.0
        cells.append(f'{np.median(b):.4g}, {np.median(v):.4g} ({(d>0).sum()}/{(d<0).sum()}, p {pv:.2f})')
    print(f'| {p} | {len(seeds)} | ' + ' | '.join(cells)+' |')
