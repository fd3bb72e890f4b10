"""The calibration loop without a robot (issue 49, must hold 2): a hidden "true" push twin records
pushes, the nominal twin is calibrated from them, the push skill is learned on the calibrated twin
and on the nominal one, and both picks are rolled out in the true twin.

    python benchmarks/calibration_loop.py --out DIR [--episodes 10] [--seed 0] [--per-config 17]
        [--steps true,record,calibrate,train,evaluate] [--train-args "..."]

Steps, each skipped when its output is there (a killed loop goes on where it stopped):

* ``true``: ``DIR/true.yaml``, push.yaml with the pushed prism 20 % heavier, its friction 50 %
  higher and its centre of mass 2 cm further along x (``mjxskill.calibration.record.TRUE_CHANGES``),
  one friction in every world (the randomization's range dropped);
* ``record``: ``DIR/recordings/epNN.npz``, ``--episodes`` pushes in the true twin with the noise
  of push.yaml's ``calibration.noise`` (``record_episodes``: the operators' sets in turn, each
  changed by up to 1 cm, from the training start configurations in turn);
* ``calibrate``: ``python -m mjxskill.calibrate push --recordings DIR/recordings --out
  DIR/calibrated.yaml`` (and its report, ``DIR/calibrated.report/``), then each fitted value
  against the true one: its error, whether its interval covers the true value
  (``DIR/recovery.json``; must hold 1: mass and friction within 10 %, the centre of mass within
  5 mm, every interval covering);
* ``train``: ``python -m mjxskill.train`` on ``DIR/calibrated.yaml`` and on ``push``, the robust
  protocol at the scenario's budget (``--train-args`` adds flags to both, e.g. ``--budget 60``),
  into ``DIR/runs/calibrated`` and ``DIR/runs/nominal``;
* ``evaluate``: each run's pick (its race's winner) rolled out in the true twin, ``--per-config``
  worlds from each of its 6 start configurations (4 known, 2 unseen: 102 worlds), the same
  worlds for both; ``DIR/loop.json`` and a line per pick. Must hold: the calibrated twin's pick
  succeeds in at least 95 % of them; the nominal one's is reported beside it.

The full loop is two training runs of the scenario's size (about 200 s each on the project's
2-core machine) and a calibration of about 8 minutes; ``tests/benchmarks/test_calibration_loop.py`` runs
its pieces at a tiny size.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np

from mjxskill import load_scenario, plan_task
from mjxskill.calibration.record import record_episodes, true_twin
from mjxskill.calibration.recording import write_npz
from mjxskill.calibration.scenario_yaml import scenario_text
from mjxskill.calibration.twin import parameter_values
from mjxskill.engine.build import build_rollout

STEPS = ("true", "record", "calibrate", "train", "evaluate")
KEY = 49  # the evaluation worlds' key: the same worlds for both picks


def write_true_twin(out: Path) -> Path:
    """``out/true.yaml``: push.yaml with the true twin's values (module docstring)."""
    scn = load_scenario("push")
    true = true_twin(scn)
    path = out / "true.yaml"
    path.write_text(scenario_text(scn, parameter_values(true), path, friction_range=None))
    return path


def record(true_yaml: Path, folder: Path, episodes: int, seed: int) -> list[Path]:
    """``episodes`` recordings of the true twin in ``folder`` (``epNN.npz``)."""
    scn = load_scenario(true_yaml)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for k, arrays in enumerate(record_episodes(scn, plan_task(scn), episodes, seed=seed, source=f"twin {true_yaml}")):
        path = folder / f"ep{k:02d}.npz"
        path.write_bytes(write_npz(arrays))
        paths.append(path)
    return paths


def recovery(true_yaml: Path, calibrated_yaml: Path) -> dict:
    """Each fitted value of ``calibrated_yaml`` against ``true_yaml``'s: key -> {true, fitted,
    low, high, error, relative_error, covered}."""
    truth = parameter_values(load_scenario(true_yaml))
    fitted = load_scenario(calibrated_yaml).calibrated
    assert fitted is not None, f"{calibrated_yaml} holds no calibrated section"
    out = {}
    for key, (value, low, high) in fitted.values.items():
        true = truth[key]
        out[key] = {"true": true, "fitted": value, "low": low, "high": high, "error": value - true,
                    "relative_error": (value - true) / true if true else None, "covered": low <= true <= high}
    return out


def _command(module: str, *args) -> None:
    command = [sys.executable, "-m", f"mjxskill.{module}", *map(str, args)]
    print("$", shlex.join(command), flush=True)
    subprocess.run(command, check=True)


def raced_parameters(run: Path) -> np.ndarray:
    """The pick of a robust run: its race's winner's parameters."""
    from mjxskill.evaluation.racing import raced_pick  # lazy: the evaluation stack only for this step
    from mjxskill.runs.run_dir import Run

    r = Run(run)
    front = r.front(r.config())
    raced = raced_pick(r.path, front)
    if raced is None:
        raise SystemExit(f"{run} has no finished race: train it to the end (the robust protocol)")
    return np.asarray(front.params[raced[0]], float)


def success_in_twin(twin_yaml: Path, picks: dict[str, np.ndarray], per_config: int, seed: int = KEY) -> dict:
    """Each pick's success in ``per_config`` worlds from every start configuration of the twin
    (known, then unseen), the same worlds for all: name -> {known, unseen, all, worlds}."""
    scn = load_scenario(twin_yaml)
    task = plan_task(scn)
    configs = np.concatenate([scn.robot.start_configs, scn.robot.eval_configs])
    rollout = build_rollout(scn, task, "native", worlds=per_config * len(configs))
    try:
        worlds = rollout.worlds_per_config(jax.random.key(seed), per_config, configs)
        out = rollout.run_worlds(np.array(list(picks.values())), worlds)
    finally:
        rollout.close()
    success = np.asarray(out.success, bool)
    known = np.repeat(np.arange(len(configs)) < len(scn.robot.start_configs), per_config)
    return {name: {"known": float(success[i, known].mean()), "unseen": float(success[i, ~known].mean()),
                   "all": float(success[i].mean()), "worlds": int(success.shape[1])}
            for i, name in enumerate(picks)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--per-config", type=int, default=17)
    parser.add_argument("--steps", default=",".join(STEPS))
    parser.add_argument("--train-args", default="", help="flags added to both training runs")
    args = parser.parse_args(argv)
    steps = args.steps.split(",")
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    true_yaml, recordings, calibrated = out / "true.yaml", out / "recordings", out / "calibrated.yaml"
    if "true" in steps and not true_yaml.is_file():
        write_true_twin(out)
    if "record" in steps and not recordings.is_dir():
        record(true_yaml, recordings, args.episodes, args.seed)
    if "calibrate" in steps:
        if not calibrated.is_file():
            _command("calibrate", "push", "--recordings", recordings, "--out", calibrated)
        found = recovery(true_yaml, calibrated)
        (out / "recovery.json").write_text(json.dumps(found, indent=1) + "\n")
        for key, r in found.items():
            relative = f" ({r['relative_error'] * 100:+.1f} %)" if r["relative_error"] is not None else ""
            print(f"{key:34s} true {r['true']:.4g} fitted {r['fitted']:.4g} [{r['low']:.4g}, {r['high']:.4g}] "
                  f"error {r['error']:+.3g}{relative} {'covered' if r['covered'] else 'NOT covered'}")
    runs = {"calibrated": (calibrated, out / "runs" / "calibrated"), "nominal": ("push", out / "runs" / "nominal")}
    if "train" in steps:
        for scenario, run in runs.values():
            resume = ["--resume"] if run.is_dir() else []
            _command("train", scenario, "--out", run, *resume, *shlex.split(args.train_args))
    if "evaluate" in steps:
        picks = {name: raced_parameters(run) for name, (_, run) in runs.items()}
        result = success_in_twin(true_yaml, picks, args.per_config)
        doc = {"true": str(true_yaml), "picks": {n: p.tolist() for n, p in picks.items()}, "success_in_true_twin": result}
        (out / "loop.json").write_text(json.dumps(doc, indent=1) + "\n")
        for name, s in result.items():
            print(f"{name:10s} pick: {s['all'] * 100:.1f} % of {s['worlds']} worlds of the true twin "
                  f"(known {s['known'] * 100:.1f} %, unseen {s['unseen'] * 100:.1f} %)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
