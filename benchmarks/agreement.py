"""How far the two physics engines agree: success rates of the same parameter sets in the same
worlds on MJX and on native MuJoCo.

    python benchmarks/agreement.py --task push --worlds 50 --json push.json
    python benchmarks/agreement.py --task peg --worlds 50 --run runs/peg-0 --json peg.json

Parameter sets: the planner's defaults, the scenario's operator sets, the hand-found push
(push only), 5 uniform random sets (seed 0) and, with ``--run DIR`` (repeatable: e.g. one run
trained on each engine), the most successful Pareto solution of each run (ties: the first
objective). Every set runs in the same ``--worlds``
worlds (drawn from ``--key``), once on each engine. Per set: ``mjx_success_rate``,
``native_success_rate``, ``n`` (worlds), the worlds where the two agree, the mean final
position error on each engine and the relative difference of the mean objectives. A user's
question, does a solution learned on one engine succeed as often on the other, is the ratio
of the two rates for each run's solution (``transfer``: one entry per run).

The JSON: ``{"task", "worlds", "seconds", "sets": [{"name", "mjx_success_rate",
"native_success_rate", "n", ...}], "max_rate_difference", "transfer": [{"set", "trained_on",
"kept_on_the_other"}]}``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

HAND_FOUND_PUSH = (-0.05, -0.15, 0.07, -0.10)


def parameter_sets(scn, task, runs: list[Path], n_random: int = 5) -> dict:
    import numpy as np

    sets = {"planner": task.defaults}
    sets.update(task.manual_parameters)
    if scn.name == "push":
        sets["hand-found"] = np.array(HAND_FOUND_PUSH)
    rng = np.random.default_rng(0)
    for i, row in enumerate(rng.uniform(*task.bounds, size=(n_random, len(task.parameter_names)))):
        sets[f"random-{i}"] = row
    for run in runs:
        from mjxskill.runs.run_dir import Run
        from mjxskill.evaluation.selection import choose

        config = Run(run).config()
        if tuple(config.parameter_names) != tuple(task.parameter_names):
            raise SystemExit(f"{run} is a run of other parameters: {config.parameter_names}")
        front = Run(run).pareto(config)
        k = choose(front)
        sets[f"{run.name}-pareto-{k} (trained on {config.engine})"] = front.params[k]
    return {name: np.asarray(v, float) for name, v in sets.items()}


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--task", default="push")
    parser.add_argument("--worlds", type=int, default=50)
    parser.add_argument("--seconds", type=float, default=None, help="episode length (default: the scenario's)")
    parser.add_argument("--key", type=int, default=123, help="PRNG key of the worlds")
    parser.add_argument("--run", type=Path, action="append", default=[],
                        help="a run directory: its best Pareto solution joins the sets (repeatable)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)

    if "jax" not in sys.modules:  # MJX over every core: one host device per core (before jax starts)
        from mjxskill._runtime import with_host_devices  # the backend starts lazily, after this

        os.environ["XLA_FLAGS"] = with_host_devices(os.environ.get("XLA_FLAGS", ""), os.cpu_count(), keep_users=True)
    import mjxskill  # noqa: F401
    import jax
    import numpy as np

    from mjxskill import compile_rollout, load_scenario, plan_task
    from mjxskill.engine.build import build_rollout

    scn = load_scenario(args.task)
    task = plan_task(scn)
    sets = parameter_sets(scn, task, args.run)
    names, params = list(sets), np.stack(list(sets.values()))
    native = build_rollout(scn, task, "native", worlds=args.worlds, episode_seconds=args.seconds)  # one process per core
    worlds = jax.tree.map(lambda x: x[0], native.sample_worlds(jax.random.key(args.key), 1))  # (W,): one set of worlds for all
    print(f"# agreement: {scn.name}, {len(names)} parameter sets x {args.worlds} worlds, {native.episode_seconds:g} s "
          f"episodes, key {args.key}, load average {os.getloadavg()[0]:.2f}", flush=True)
    t0 = time.perf_counter()
    out_native = native.run_worlds(params, worlds)
    native_s = time.perf_counter() - t0
    native.close()
    compiled = compile_rollout(scn, task, worlds=args.worlds, episode_seconds=args.seconds)
    t0 = time.perf_counter()
    out_mjx = jax.tree.map(np.asarray, compiled.run_worlds(params, worlds))
    mjx_s = time.perf_counter() - t0
    print(f"native {native_s:.0f} s, MJX {mjx_s:.0f} s (compile included), load average {os.getloadavg()[0]:.2f}")

    rows = []
    for i, name in enumerate(names):
        sm, sn = np.asarray(out_mjx.success[i], bool), np.asarray(out_native.success[i], bool)
        om, on = np.asarray(out_mjx.objectives[i], float), np.asarray(out_native.objectives[i], float)
        rows.append(dict(
            name=name, params=params[i].tolist(), n=int(len(sm)),
            mjx_success_rate=float(sm.mean()), native_success_rate=float(sn.mean()),
            worlds_agreeing=int((sm == sn).sum()),
            worlds_mjx_only=[int(j) for j in np.flatnonzero(sm & ~sn)],
            worlds_native_only=[int(j) for j in np.flatnonzero(sn & ~sm)],
            mjx_position_error_m=float(np.mean(out_mjx.metrics["position_error"][i])),
            native_position_error_m=float(np.mean(out_native.metrics["position_error"][i])),
            mjx_diverged=int(np.sum(out_mjx.metrics["diverged"][i])),
            native_diverged=int(np.sum(out_native.metrics["diverged"][i])),
            objective_relative_difference=[float(abs(a - b) / max(abs(b), 1e-9)) for a, b in zip(om, on)],
        ))
    result = dict(task=scn.name, worlds=args.worlds, seconds=native.episode_seconds, key=args.key, sets=rows,
                  max_rate_difference=max(abs(r["mjx_success_rate"] - r["native_success_rate"]) for r in rows),
                  load_avg=os.getloadavg()[0])
    result["transfer"] = []
    for r in (r for r in rows if "trained on" in r["name"]):
        own, other = ("mjx", "native") if "trained on mjx" in r["name"] else ("native", "mjx")
        kept = r[f"{other}_success_rate"] / r[f"{own}_success_rate"] if r[f"{own}_success_rate"] else float("nan")
        result["transfer"].append(dict(set=r["name"], trained_on=own, kept_on_the_other=kept))

    width = max(len(r["name"]) for r in rows)
    print(f"\n{'set':<{width}}  {'MJX':>5}  {'native':>6}  agree  pos.err MJX/native [mm]  objectives rel. diff")
    for r in rows:
        print(f"{r['name']:<{width}}  {r['mjx_success_rate']:>5.0%}  {r['native_success_rate']:>6.0%}  "
              f"{r['worlds_agreeing']:>2}/{r['n']:<2}  {1000 * r['mjx_position_error_m']:>8.1f} / "
              f"{1000 * r['native_position_error_m']:<8.1f}      "
              + " ".join(f"{d:.1e}" for d in r["objective_relative_difference"]))
    print(f"\nlargest success-rate difference: {result['max_rate_difference']:.2f} (must be <= 0.15)")
    for t in result["transfer"]:
        print(f"{t['set']}: keeps {t['kept_on_the_other']:.0%} of its success rate on the other engine (must be >= 90 %)")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
