"""The experiments' figures quoted in README.md and docs/experiments/*/README.md are their reports':
the total wall time (the sum of the report's wall-time table, within 2 %) and the hypervolume
p-value, read from report.json, so that the prose cannot drift from the files."""

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENTS = sorted(p.parent for p in (ROOT / "docs" / "experiments").glob("*/report.json"))
STEPS = ("train_seconds", "evaluate_seconds", "validate_seconds", "race_seconds", "confirm_seconds")


def report_wall_seconds(report: dict) -> float:
    """What the report's wall-time table sums to: both runs' training, the evaluation and the pick."""
    return sum(kinds[kind].get(step, 0.0) for kinds in report["wall_time"].values()
               for kind in ("optimizer", "random_search") for step in STEPS)


NUMBER = r"(?<![\d,.])(\d{1,3}(?:,\d{3})+|\d{3,6})"  # 11950 or 11,950, never a tail of either


def _quoted(text: str, pattern: str) -> list[float]:
    return [float(v.replace(",", "")) for v in re.findall(pattern, text)]


@pytest.mark.parametrize("path", EXPERIMENTS, ids=[p.name for p in EXPERIMENTS])
def test_the_wall_time_quoted_is_the_reports(path):
    report = json.loads((path / "report.json").read_text())
    if report["status"]["repetitions_done"] < report["status"]["repetitions"]:
        pytest.skip(f"{path.name} is not finished: its README quotes no total yet")
    total = report_wall_seconds(report)
    readme = (path / "README.md").read_text()
    quoted = _quoted(readme, NUMBER + r" s\s+(?:for the ten repetitions|in all for the ten repetitions)")
    quoted += _quoted(readme, NUMBER + r" s\s+in all\b")
    assert quoted, f"{path / 'README.md'} quotes no total wall time"
    for value in quoted:
        assert value == pytest.approx(total, rel=0.02), (path.name, value, total)
    top = (ROOT / "README.md").read_text()
    link = re.escape(f"[`docs/experiments/{path.name}/`](docs/experiments/{path.name}/)") + r" \((\d+) s\)"
    for value in _quoted(top, link):
        assert value == pytest.approx(total, rel=0.02), ("README.md", path.name, value, total)


@pytest.mark.parametrize("path", EXPERIMENTS, ids=[p.name for p in EXPERIMENTS])
def test_the_hypervolume_p_quoted_is_the_reports(path):
    report = json.loads((path / "report.json").read_text())
    if report["status"]["repetitions_done"] < report["status"]["repetitions"]:
        pytest.skip(f"{path.name} is not finished: its README quotes no p over the ten yet")
    p = report["hypervolume"]["mann_whitney_p_final"]
    readme = (path / "README.md").read_text()
    quoted = _quoted(readme, r"p = ([0-9.]+e-\d+|0\.\d+)[^0-9]*(?:exact|the smallest p|over the ten)")
    assert quoted, f"{path / 'README.md'} quotes no hypervolume p-value"
    for value in quoted:
        assert value == pytest.approx(p, rel=0.05), (path.name, value, p)
