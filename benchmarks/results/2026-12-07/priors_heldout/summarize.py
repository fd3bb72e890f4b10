"""The must-hold-4 table from the saved runs: per problem, the misleading prior against none at
60 evaluations and the good prior against none at 20, in decades of the log hypervolume gap
(benchmarks/mobo_priors.py's docstring), about the reference the same seed's no-prior run infers
(own) and about the problem's (problem), with Mann-Whitney p.

    python benchmarks/results/2026-12-07/priors_heldout/summarize.py FILE.json [...]
"""
import contextlib
import io
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", ".."))
import mobo_priors as mp  # noqa: E402


def cell(o, none, key, i):
    if o is None or not len(o[key]) or not len(none[key]):
        return "-"
    d = np.median(o[key][:, i]) - np.median(none[key][:, i])
    return f"{d:+.2f} (p {mp.mann_whitney(o[key][:, i], none[key][:, i]):.2g})"


def main(paths):
    with contextlib.redirect_stdout(io.StringIO()):
        out = mp.report(mp.load_saved(paths))
    print("| problem | misleading @ 60, own | misleading @ 60, problem's ref | good @ 20, own | good @ 20, problem's ref |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, r in out.items():
        cps = mp.checkpoints_of(60)
        i20, i60 = cps.index(20), cps.index(60)
        row = [cell(r.get(k), r["none"], key, i) for k, i in (("misleading", i60), ("good", i20))
               for key in ("log_gap", "log_gap_problem_ref")]
        print(f"| {name} | " + " | ".join(row) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
