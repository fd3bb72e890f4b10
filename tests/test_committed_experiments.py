"""The committed experiments recompute from their files: every figure of report.json, the picks
among them, again and exactly, for the paper's protocol (docs/experiments/peg, push: runs of
before the protocol setting, read as "paper") and the robust one (docs/experiments/*-robust)."""

import json
from pathlib import Path

import pytest

from mjxskill.experiment.directory import Experiment
from mjxskill.experiment.stats import summarize

ROOT = Path(__file__).resolve().parent.parent
# every committed experiment has its report (written after each repetition)
EXPERIMENTS = sorted(p.parent for p in (ROOT / "docs" / "experiments").glob("*/report.json"))


def _plain(value):
    """JSON's view of a value (tuples as lists, no NaN): what report.json holds."""
    return json.loads(json.dumps(value))


@pytest.mark.parametrize("path", EXPERIMENTS, ids=[p.name for p in EXPERIMENTS])
def test_the_committed_report_recomputes_exactly(path):
    committed = json.loads((path / "report.json").read_text())
    summary = _plain(summarize(Experiment(path)))
    assert summary.keys() == committed.keys()
    for key in committed:
        assert summary[key] == committed[key], key
    assert summary["status"]["repetitions_done"] >= 1


def test_the_paper_protocol_experiments_are_read_as_the_paper_protocol():
    paper = [p for p in EXPERIMENTS if Experiment(p).config().protocol == "paper"]
    assert {p.name for p in paper} >= {"peg", "push"}
