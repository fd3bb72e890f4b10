"""Where the peg's robust picks fail: the approach, the spiral's start and the tool's lag (issue 43).

    python benchmarks/peg_approach.py threshold --per-config 12 --json FILE
    python benchmarks/peg_approach.py trace 13 8 --set pick0

``threshold`` rolls a few sets (the first robust picks of docs/experiments/peg-robust and the
illustrative ``operator_b``) out in the same worlds, ``--per-config`` from each of the 15 start
configurations, once with the shipped peg scenario and once with the approach skill done at
5 mm from its pose instead of 5 cm (``GoToLinear.threshold``, SkiREIL's 0.05: the insertion
starts its spiral while the reference still descends), and prints success per configuration.
``trace`` prints one episode every 0.1 s: the tool's and the reference's offsets from the hole
and their heights (start configuration index, world index among ``--per-config`` worlds).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import jax
import numpy as np

from mjxskill import load_scenario, plan_task
from mjxskill.engine.build import build_rollout
from mjxskill.sim import asset_path

GOAL = "(skiros:at skiros:Peg-1 skiros:BoxWithHole-1)"
SETS = {"pick0": [-7.614, 0.07, 0.03859], "operator_b": [-8.0, 0.02, 0.05],
        "pick1": [-5.954, 0.04021, 0.03929], "pick3": [-6.591, 0.05706, 0.0444]}
KEY = 11


def settled_scenario(threshold: float) -> Path:
    """A copy of the shipped peg scenario whose approach ends ``threshold`` m from its pose."""
    source = asset_path() / "scenarios" / "peg.yaml"
    text = source.read_text()
    text = text.replace("scene: ../peg.xml", f"scene: {asset_path() / 'peg.xml'}")
    text = text.replace("skill_library: ../skills/library.yaml", f"skill_library: {asset_path() / 'skills' / 'library.yaml'}")
    text += f"\nskill_parameters:\n  GoToLinear.threshold: {{default: {threshold}}}\n"
    with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
        f.write(text)
    return Path(f.name)


def all_configs(scn) -> np.ndarray:
    return np.concatenate([np.asarray(scn.robot.start_configs), np.asarray(scn.robot.eval_configs)])


def success_by_config(scenario, per_config: int) -> dict:
    scn = load_scenario(str(scenario))
    task = plan_task(scn, GOAL)
    configs = all_configs(scn)
    params = np.array(list(SETS.values()))
    with build_rollout(scn, task, "native", worlds=per_config * len(configs), episode_seconds=18.0, workers=1) as r:
        worlds = r.worlds_per_config(jax.random.PRNGKey(KEY), per_config, configs)
        out = r.run_worlds(params, worlds)
    s = np.asarray(out.success).reshape(len(params), len(configs), per_config).mean(2)
    known = len(scn.robot.start_configs)
    return {name: {"known": float(row[:known].mean()), "unseen": float(row[known:].mean()),
                   "per_config": [float(x) for x in row]} for name, row in zip(SETS, s)}


def threshold(args) -> int:
    doc = {"per_config": args.per_config, "key": KEY, "sets": SETS, "shipped": success_by_config("peg", args.per_config)}
    settled = settled_scenario(args.threshold)
    try:
        doc[f"threshold_{args.threshold}"] = success_by_config(settled, args.per_config)
    finally:
        settled.unlink()
    for variant in ("shipped", f"threshold_{args.threshold}"):
        print(variant)
        for name, row in doc[variant].items():
            print(f"  {name:10s} known {row['known']:.3f} unseen {row['unseen']:.3f} |",
                  " ".join(f"{x * 100:3.0f}" for x in row["per_config"]))
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1))
    return 0


def trace(args) -> int:
    scn = load_scenario("peg")
    task = plan_task(scn, GOAL)
    configs = all_configs(scn)
    with build_rollout(scn, task, "native", worlds=args.per_config, episode_seconds=18.0, workers=1) as r:
        worlds = r.worlds_per_config(jax.random.PRNGKey(7), args.per_config, configs[args.config:args.config + 1])
        world = jax.tree.map(lambda a: np.asarray(a)[args.world], worlds)
        result, record = r.trace(np.array(SETS[args.set]), world)
    hole = np.asarray(world.object_pos)[0]
    tool, ref = np.asarray(record.tool_pos), np.asarray(record.ref_pos)
    print(f"box at {np.round(hole * 1000, 1)} mm, success {bool(result.success)}")
    step = max(1, int(scn.bt_hz / 10))
    for t in range(0, len(tool), step):
        d, dr = (tool[t, :2] - hole[:2]) * 1000, (ref[t, :2] - hole[:2]) * 1000
        print(f"{t / scn.bt_hz:5.2f} s  tool - hole {np.round(d, 1)} ({np.linalg.norm(d):5.1f} mm)  "
              f"reference - hole {np.round(dr, 1)} ({np.linalg.norm(dr):5.1f} mm)  "
              f"tool z {tool[t, 2] * 1000:6.1f} mm, reference z {ref[t, 2] * 1000:6.1f} mm")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    th = sub.add_parser("threshold")
    th.add_argument("--per-config", type=int, default=12)
    th.add_argument("--threshold", type=float, default=0.005)
    th.add_argument("--json", type=Path)
    tr = sub.add_parser("trace")
    tr.add_argument("config", type=int)
    tr.add_argument("world", type=int)
    tr.add_argument("--set", choices=tuple(SETS), default="pick0")
    tr.add_argument("--per-config", type=int, default=20)
    args = parser.parse_args(argv)
    return threshold(args) if args.command == "threshold" else trace(args)


if __name__ == "__main__":
    sys.exit(main())
