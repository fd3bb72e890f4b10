"""Episodes/s of one call of the native engine with and without a Ray cluster (issue 34).

    python benchmarks/ray_throughput.py --address HOST:PORT [--sets 6 --worlds 7 --seconds 12 --repeats 3] [--json FILE]

Rolls out ``sets`` x ``worlds`` push episodes (worlds from key 0) ``repeats`` times in one
process with the default worker processes, then on the cluster's actors (one per CPU, started
before the clock runs), checks the results agree bit for bit and prints the median episodes/s
and control steps/s of each (``--json``: the same with the load average, the commit and the
cluster's description). docs/engines.md, "Running on a Ray cluster", projects from it.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import time
from pathlib import Path

import jax
import numpy as np

from mjxskill import load_scenario, plan_task
from mjxskill.engine.build import build_rollout, connect_cluster


def timed(rollout, params, worlds, repeats: int):
    rollout.run_worlds(params, worlds)  # warm: workers or actors started, first batch built
    seconds, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = rollout.run_worlds(params, worlds)
        seconds.append(time.perf_counter() - t0)
    return statistics.median(seconds), out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--address", required=True)
    parser.add_argument("--sets", type=int, default=6)
    parser.add_argument("--worlds", type=int, default=7)
    parser.add_argument("--seconds", type=float, default=12.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path, help="write the figures here")
    args = parser.parse_args()
    scn = load_scenario("push")
    task = plan_task(scn)
    lower, upper = np.asarray(task.bounds)
    params = lower + (upper - lower) * np.random.default_rng(0).random((args.sets, len(lower)))
    episodes = args.sets * args.worlds
    results, rows = {}, []
    for name, cluster in (("local (default workers)", None), ("ray", connect_cluster(args.address))):
        with build_rollout(scn, task, "native", worlds=args.worlds, episode_seconds=args.seconds, cluster=cluster) as rollout:
            worlds = rollout.sample_worlds(jax.random.key(0), args.sets)
            seconds, out = timed(rollout, params, worlds, args.repeats)
            steps = episodes * rollout.setup.ticks * rollout.setup.steps_per_tick  # control steps, diverged ones counted whole
            where = "" if cluster is None else f" ({cluster.describe()})"
            results[name] = out
            rows.append({"engine": name, "cluster": cluster.describe() if cluster else None, "episodes": episodes,
                         "median_seconds": seconds, "episodes_per_s": episodes / seconds,
                         "control_steps_per_s": steps / seconds, "load_average": os.getloadavg()[0]})
            print(f"{name}{where}: {episodes} episodes of {args.seconds:g} s in {seconds:.2f} s (median of "
                  f"{args.repeats}): {episodes / seconds:.2f} episodes/s"
                  f", {steps / seconds:,.0f} control steps/s", flush=True)
    a, b = results.values()
    np.testing.assert_array_equal(a.objectives, b.objectives)
    print("results identical: yes")
    if args.json is not None:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).resolve().parent).stdout.strip()
        args.json.write_text(json.dumps({"sets": args.sets, "worlds": args.worlds, "seconds": args.seconds,
                                         "repeats": args.repeats, "commit": commit, "results_identical": True,
                                         "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
