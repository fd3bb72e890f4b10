"""What a fit writes beside the calibrated scenario: the report, and the ``calibrated`` section.

The report is a folder of three files:

* ``report.html``: ``mujoco.sysid``'s own report (``sysid.default_report``: the parameters before
  and after, every recorded signal against the simulated one before and after the fit, the
  measured torques, the parameters' distribution and covariance, the optimizer's trace; plotly,
  loaded from its CDN when the page is opened);
* ``trajectories.png``: per recording the tracked object's x, y and yaw and the tool force,
  recorded against simulated with the nominal and with the fitted values, over the fit's window;
* ``report.md``: the fitted values with both intervals, what they were fitted from, the RMS error
  of each signal per recording before and after, and the optimizer's log.
"""

from __future__ import annotations

import hashlib
import io
import json
from pathlib import Path

import numpy as np
from mujoco import sysid

from mjxskill._headless import pyplot
from mjxskill.calibration.fit import FitResult

UNITS = {"joint_position": "rad", "object_position": "m", "object_quaternion": "", "tool_force": "N"}


def sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _yaw(q: np.ndarray) -> np.ndarray:
    """Rotation about world z (deg) of quaternions (N, 4) w x y z."""
    return np.degrees(np.arctan2(2 * (q[:, 0] * q[:, 3] + q[:, 1] * q[:, 2]), 1 - 2 * (q[:, 2] ** 2 + q[:, 3] ** 2)))


def trajectories_png(fit: FitResult, limit: int = 10) -> bytes:
    """The figure of the module docstring (the first ``limit`` recordings), as PNG bytes."""
    plt = pyplot()
    replays = fit.sysid["replays"][:limit]
    before, after = (p[:limit] for p in fit.sysid["predicted"])
    measured = fit.sysid["measured"][:limit]
    columns = [("object x (m)", lambda d, c: d[:, c["object_x"]]), ("object y (m)", lambda d, c: d[:, c["object_y"]]),
               ("object yaw (deg)", lambda d, c: _yaw(d[:, [c[k] for k in ("object_qw", "object_qx", "object_qy", "object_qz")]])),
               ("tool force (N)", lambda d, c: d[:, c["tool_force"]] if "tool_force" in c else np.full(len(d), np.nan))]
    fig, axes = plt.subplots(len(replays), len(columns), figsize=(14, 2.2 * len(replays)), squeeze=False)
    for row, (replay, b, a, m) in enumerate(zip(replays, before, after, measured)):
        index = {name: k for k, name in enumerate(replay.columns)}
        t = m[0].times
        for col, (title, pick) in enumerate(columns):
            ax = axes[row][col]
            ax.plot(t, pick(m[0].data, index), ".", color="black", markersize=2, label="recorded")
            ax.plot(t, pick(b[0].data, index), color="tab:red", label="nominal twin")
            ax.plot(t, pick(a[0].data, index), color="tab:blue", label="calibrated twin")
            if row == 0:
                ax.set_title(title)
            if col == 0:
                ax.set_ylabel(Path(replay.recording.path).name, fontsize=8)
    axes[0][0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=90, format="png")
    plt.close(fig)
    return buffer.getvalue()


def sysid_html(fit: FitResult, title: str) -> bytes:
    """``sysid.default_report`` of the fit (no videos: they need the scene rendered)."""
    s = fit.sysid
    builder = sysid.default_report([s["sequences"]], s["initial"], s["fitted"], s["residual_fn"], s["result"], title=title,
                                   save_path=None, build_model=s["build_model"], generate_videos=False)
    return builder.build().encode()


def markdown(fit: FitResult, scenario: str, command: str, sources: list[str]) -> str:
    """``report.md`` (the module docstring)."""
    level = f"{fit.confidence * 100:g} %"
    lines = [f"# Calibration of {scenario}", "", f"`{command}`", "",
             f"Fitted with mujoco.sysid to {len(sources)} recordings in {fit.seconds:.0f} s "
             f"({fit.evaluations} residual evaluations, {fit.episodes} replayed episodes): {fit.message}", "",
             f"| parameter | nominal | fitted | {level} interval (recordings as clusters) | sysid's {level} interval | bounds |",
             "| --- | ---: | ---: | --- | --- | --- |"]
    for p, n, v, h, th in zip(fit.parameters, fit.nominal, fit.values, fit.half_width, fit.toolbox_half_width):
        unit = f" {p.unit}" if p.unit else ""
        lines.append(f"| {p.key} | {n:.4g}{unit} | **{v:.4g}**{unit} | [{v - h:.4g}, {v + h:.4g}] | [{v - th:.4g}, {v + th:.4g}] "
                     f"| [{p.bounds[0]:g}, {p.bounds[1]:g}] |")
    lines += ["", f"Residual (sum of squares in noise units, {fit.samples} values): {fit.cost[0]:.4g} with the nominal "
              f"values, {fit.cost[1]:.4g} fitted.", "", "## Fitted from", ""]
    lines += [f"- `{s}`" for s in sources]
    lines += ["", "## RMS error per recording, nominal -> fitted (over the fit's window)", "",
              "| recording | window (s) | " + " | ".join(f"{s} ({UNITS[s]})" if UNITS[s] else s for s in UNITS) + " |",
              "| --- | --- |" + " ---: |" * len(UNITS)]
    for replay in fit.sysid["replays"]:
        rec = replay.recording
        rms = fit.rms[rec.path]
        cells = [f"{rms[s][0]:.3g} -> {rms[s][1]:.3g}" if s in rms else "-" for s in UNITS]
        lines.append(f"| {Path(rec.path).name} | {rec.time[replay.first]:.2f}-{rec.time[replay.last - 1]:.2f} | "
                     + " | ".join(cells) + " |")
    lines += ["", "## The optimizer", "", "```", fit.log.strip(), "```", ""]
    return "\n".join(lines)


def calibrated_section(fit: FitResult, sources: list[str], report: str, command: str) -> str:
    """The ``calibrated`` YAML block the calibrated scenario ends with (``mjxskill.scenario.calibration``)."""
    lines = [f"# Written by mjxskill.calibrate: the values of {len(fit.parameters)} entries above were fitted to the "
             "recordings below", f"# (mujoco.sysid; the report: {report}).", "calibrated:", "  values:"]
    for p, n, v, h in zip(fit.parameters, fit.nominal, fit.values, fit.half_width):
        unit = f", unit: {p.unit}" if p.unit else ""
        lines.append(f"    {p.key}: {{value: {v:.6g}, low: {v - h:.6g}, high: {v + h:.6g}, nominal: {n:.6g}{unit}}}")
    lines.append(f"  confidence: {fit.confidence:g}")
    lines.append("  sources:")
    lines += [f"    - {json.dumps(s)}" for s in sources]  # JSON strings are YAML's double-quoted ones
    lines.append(f"  report: {json.dumps(report)}")
    lines.append(f"  command: {json.dumps(command)}")
    return "\n".join(lines) + "\n"


__all__ = ["calibrated_section", "markdown", "sha256", "sysid_html", "trajectories_png"]
