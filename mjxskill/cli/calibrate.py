"""``python -m mjxskill.calibrate SCENARIO --recordings DIR --out calibrated.yaml``: the twin's
physics fitted to what the robot recorded.

Fits the physical values the scenario's ``calibration`` section declares (the tracked object's
mass, friction, centre of mass, within the section's bounds) to the recordings in DIR (every
``*.npz``, one executed episode each: ``mjxskill.calibration.recording``) with ``mujoco.sysid``
(``pip install 'mjxskill[calibrate]'``), and writes the scenario with the fitted values, their
intervals and what they were fitted from (``--out``), and beside it the report (a folder named
after it, ``calibrated.report/``). Every recording is read and checked before the fit starts; a
bad one is one ``error:`` line naming the file, the array and the sample (exit code 2). What is
there already is only replaced with ``--replace``.

    python -m mjxskill.calibrate push --recordings recordings/ --out push-calibrated.yaml
    python -m mjxskill.train push-calibrated.yaml --out runs/push-calibrated

docs/calibration.md: the loop on a real robot, what to record, how many episodes.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path
from typing import Sequence

from mjxskill import cli
from mjxskill.calibration import missing_extra
from mjxskill.calibration.fit import FitResult, calibrate
from mjxskill.calibration.recording import read_recording
from mjxskill.calibration.report import calibrated_section, markdown, sha256, sysid_html, trajectories_png
from mjxskill.calibration.scenario_yaml import scenario_text
from mjxskill.cli.args import add_task_argument, int_in
from mjxskill.errors import CommandError, RunError, ScenarioError
from mjxskill.runs.atomic_write import DISK_FAULTS
from mjxskill.runs.outputs import check_outputs, write_outputs
from mjxskill.scenario import load_scenario
from mjxskill.scenario.calibration import outside
from mjxskill.task import plan_task

MAX_RECORDINGS = 1000


def confidence_level(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0.5 <= value < 1:
        raise argparse.ArgumentTypeError(f"expected a probability in [0.5, 1), got {text}")
    return value


confidence_level.__name__ = "confidence level"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.calibrate", description="Fit the twin's physics to recorded episodes.")
    add_task_argument(parser)
    parser.add_argument("--recordings", type=Path, required=True, metavar="DIR",
                        help="folder of recordings, one executed episode per .npz file (docs/calibration.md)")
    parser.add_argument("--out", type=Path, required=True, metavar="FILE",
                        help="the calibrated scenario YAML to write; the report goes into FILE's name + .report/")
    parser.add_argument("--replace", action="store_true", help="replace an --out file or report that holds other content")
    parser.add_argument("--max-evaluations", type=int_in(2, 1000), default=40, metavar="N",
                        help="residual evaluations the optimizer may make (default 40; each replays every recording)")
    parser.add_argument("--confidence", type=confidence_level, default=0.95, metavar="P",
                        help="the intervals' confidence level (default 0.95)")
    return parser


def recording_files(folder: Path) -> list[Path]:
    """The ``*.npz`` files of ``folder``, sorted; CommandError for a folder that is none or has none."""
    if not folder.is_dir():
        raise CommandError(f"--recordings {str(folder)!r}: not a folder")
    files = sorted(p for p in folder.iterdir() if p.suffix == ".npz")
    if not files:
        raise CommandError(f"--recordings {str(folder)!r}: no recording (.npz file) in it")
    if len(files) > MAX_RECORDINGS:
        raise CommandError(f"--recordings {str(folder)!r}: {len(files)} recordings, more than the {MAX_RECORDINGS} a fit takes")
    return files


def outputs(out: Path) -> tuple[Path, Path]:
    if out.suffix not in (".yaml", ".yml"):
        raise CommandError(f"--out {str(out)!r}: a scenario is a .yaml file")
    return out, out.with_name(out.stem + ".report")


def _write(root: Path, files: dict, replace: bool) -> None:
    try:
        write_outputs(root, files, replace=replace, hint="move it away, or write elsewhere", flag="--replace")
    except OSError as err:
        if err.errno in DISK_FAULTS:  # the machine's, not the input's: exit 1
            raise
        raise CommandError(f"cannot write {root}: {err.strerror}") from None


def _summary(fit: FitResult) -> str:
    lines = [f"{'parameter':36s} {'nominal':>9s} {'fitted':>9s}  {fit.confidence * 100:g} % interval"]
    for p, n, v, lo, hi in zip(fit.parameters, fit.nominal, fit.values, fit.low, fit.high):
        lines.append(f"{p.key:36s} {n:9.4g} {v:9.4g}  [{lo:.4g}, {hi:.4g}] {p.unit}")
    lines.append(f"residual {fit.cost[0]:.4g} -> {fit.cost[1]:.4g} ({fit.samples} values), {fit.seconds:.0f} s, "
                 f"{fit.episodes} episodes replayed: {fit.message}")
    return "\n".join(lines)


def _main(args: argparse.Namespace, argv: Sequence[str]) -> int:
    problem = missing_extra()
    if problem is not None:
        raise CommandError(problem)
    out, report = outputs(args.out)
    root = out.resolve().parent
    try:  # refused now, not after minutes of fitting
        check_outputs(root, {root / out.name: b"\0", root / report.name: {"report.md": b"\0"}}, replace=args.replace,
                      hint="move it away, or write elsewhere", flag="--replace")
    except RunError as err:
        raise CommandError(str(err)) from None
    scn = load_scenario(args.task)
    if scn.calibration is None:
        raise CommandError(f"{scn.source}: the scenario has no calibration section: it declares nothing to fit "
                           "(docs/calibration.md)")
    refused = outside(scn.calibration)
    if refused is not None:
        raise ScenarioError(refused)
    task = plan_task(scn)
    files = recording_files(args.recordings)
    recordings = [read_recording(p, scn, task) for p in files]
    print(f"fitting {len(scn.calibration.parameters)} values of {scn.name} to {len(recordings)} recordings "
          "(minutes: every residual evaluation replays each recording)", file=sys.stderr, flush=True)
    fit = calibrate(scn, task, recordings, max_evaluations=args.max_evaluations, confidence=args.confidence)
    sources = [f"{p.name} sha256:{sha256(p)}" for p in files]
    command = " ".join(["python -m mjxskill.calibrate", *(shlex.quote(a) for a in argv)])
    values = {p.key: float(v) for p, v in zip(fit.parameters, fit.values)}
    friction = [k for k, p in enumerate(fit.parameters) if p.field == "friction" and p.object == scn.calibration.tracked]
    friction_range: object = False
    if friction and scn.randomization.friction_range is not None:  # the worlds' friction: the fitted interval
        k = friction[0]
        friction_range = (max(float(fit.low[k]), 1e-6), float(fit.high[k]))
    text = scenario_text(scn, values, root / out.name, friction_range=friction_range,
                         calibrated=calibrated_section(fit, sources, f"{report.name}/report.md", command))
    folder = {"report.md": markdown(fit, scn.name, command, sources).encode(),
              "report.html": sysid_html(fit, f"mjxskill calibration: {scn.name}"),
              "trajectories.png": trajectories_png(fit)}
    _write(root, {root / out.name: text.encode(), root / report.name: folder}, args.replace)
    print(_summary(fit))
    print(f"wrote {out} and {report}/ (report.md, report.html, trajectories.png)")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    arguments = list(sys.argv[1:] if argv is None else argv)  # the command the scenario records: the one parsed
    return cli.run(lambda args: _main(args, arguments), build_parser(), arguments)
