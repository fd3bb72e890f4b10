"""Optimizer overhead: time to propose one batch of 8 with 400 observations, 2 objectives.

Prints the first ask (compile + run) and the median of later asks in the same padded-size
bucket (compiled), plus, as a yardstick of how loaded the machine is, the time of a numpy
float64 Cholesky of the same padded size measured in the same run, and the 1-min load average
before and after. ``--json FILE`` writes the same figures (and the options) for a results folder.

    python benchmarks/gp_overhead.py [--n 400] [--d 4] [--q 8] [--repeats 5] [--option KEY=VALUE ...] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # see RESULTS.md: threads thrash on 2 cores

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import mjxskill  # noqa: E402,F401

from mjxskill.gp import MOBOConfig, acquisition_settings, ask, init, tell  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=400)
    ap.add_argument("--d", type=int, default=4)
    ap.add_argument("--q", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                    help="acquisition setting of mjxskill.gp (repeatable), e.g. model=per_objective")
    ap.add_argument("--json", help="write the figures to this file as JSON")
    args = ap.parse_args(argv)
    try:
        settings = acquisition_settings(dict(kv.partition("=")[::2] for kv in args.option))
    except ValueError as err:
        ap.error(f"--option: {err}")
    load_before = os.getloadavg()[0]
    rng = np.random.default_rng(0)
    cfg = MOBOConfig(bounds=[[0.0] * args.d, [1.0] * args.d], n_objectives=2, batch_size=args.q, n_init=40,
                     acquisition=settings)
    x = rng.random((args.n, args.d))
    y = np.stack([np.sum((x - 0.2) ** 2, 1), np.sum((x - 0.8) ** 2, 1)], 1) + 0.01 * rng.standard_normal((args.n, 2))
    state = tell(init(cfg), x, y)
    t = time.perf_counter()
    ask(state)
    first = time.perf_counter() - t
    times = []
    for i in range(args.repeats):
        # Growing data inside the bucket: the compiled proposal is reused.
        xi = rng.random((1, args.d))
        state = tell(state, xi, np.stack([np.sum((xi - 0.2) ** 2, 1), np.sum((xi - 0.8) ** 2, 1)], 1))
        t = time.perf_counter()
        ask(state)
        times.append(time.perf_counter() - t)
    size = settings.bucket * -(-len(state.x) // settings.bucket)
    a = rng.random((size, size))
    a = a @ a.T + size * np.eye(size)
    t = time.perf_counter()
    for _ in range(10):
        np.linalg.cholesky(a)
    chol = (time.perf_counter() - t) / 10
    run = float(np.median(times))
    print(f"n={args.n} d={args.d} q={args.q} padded rows={size}" + (f" options {' '.join(args.option)}" if args.option else ""))
    print(f"first ask (compile + run): {first:.1f} s")
    print(f"compiled ask: median {run:.2f} s over {args.repeats} (min {min(times):.2f}, max {max(times):.2f})")
    print(f"numpy Cholesky {size}x{size}: {chol * 1e3:.2f} ms; ask / Cholesky = {run / chol:.0f}")
    load_after = os.getloadavg()[0]
    print(f"1-min load: {load_before:.2f} before, {load_after:.2f} after")
    if args.json:
        doc = {"n": args.n, "d": args.d, "q": args.q, "padded_rows": size, "options": args.option, "first_ask_s": first,
               "ask_median_s": run, "ask_s": times, "cholesky_s": chol, "load1_before": load_before,
               "load1_after": load_after}
        with open(args.json, "w") as fh:
            json.dump(doc, fh, indent=1)


if __name__ == "__main__":
    main()
