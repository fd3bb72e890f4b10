"""The committed experiments recompute from their files: every figure of report.json, the picks
among them, again and exactly, for the paper's protocol (docs/experiments/peg, push: runs of
before the protocol setting, read as "paper") and the robust one (docs/experiments/*-robust); and
the committed results hold each planning file once (an experiment: at its root, as a new one)."""

import hashlib
import json
from pathlib import Path

import pytest

from mjxskill.experiment.directory import Experiment
from mjxskill.experiment.stats import summarize

ROOT = Path(__file__).resolve().parents[2]
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


PLANNING = ("domain.pddl", "problem.pddl", "plan.txt", "bt.txt")
# one committed result each: an experiment, a benchmark's output folder
RESULTS = sorted(p for p in (ROOT / "docs" / "experiments").iterdir() if p.is_dir()) + sorted(
    p for p in (ROOT / "benchmarks" / "results").iterdir() if p.is_dir())


def _planning_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file() and (p.suffix == ".pddl" or p.name in PLANNING))


@pytest.mark.parametrize("path", RESULTS, ids=[p.relative_to(ROOT).as_posix() for p in RESULTS])
def test_a_committed_result_holds_no_two_identical_planning_files(path):
    by_digest: dict[str, list[str]] = {}
    for file in _planning_files(path):
        by_digest.setdefault(hashlib.sha256(file.read_bytes()).hexdigest(), []).append(file.relative_to(path).as_posix())
    assert [files for files in by_digest.values() if len(files) > 1] == []


@pytest.mark.parametrize("path", EXPERIMENTS, ids=[p.name for p in EXPERIMENTS])
def test_a_committed_experiment_holds_its_planning_files_at_its_root_as_a_new_one_does(path):
    assert [p.relative_to(path).as_posix() for p in _planning_files(path)] == sorted(PLANNING)
