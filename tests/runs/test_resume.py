"""A resume never drops rows silently. Damaged or reordered evaluations.csv
files, resumed with the training loop and a closed-form objective (no physics): what can be
used is used, what cannot is set aside beside the file with its reason, the original is kept
byte for byte, only the missing batches are evaluated, and the run ends with the results of an
uninterrupted one."""

import csv
import math
import re

import numpy as np
import pytest

from mjxskill.errors import Notice
from mjxskill.training.loop import train
from mjxskill.runs.resume import SET_ASIDE
from mjxskill.runs.run_dir import EVALUATIONS, PARETO, Run
from toy_runs import CONFIG, Recorder, new_run

# CONFIG: batches of 4, 2, 4 (lines 2-5, 6-7 and 8-11 of the file, after the header on line 1)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted run: its evaluations.csv lines and pareto.csv text."""
    run = new_run(tmp_path_factory.mktemp("reference"), "full")
    train(run, CONFIG, Recorder())
    return (run.path / EVALUATIONS).read_text().splitlines(keepends=True), (run.path / PARETO).read_text()


def resume(tmp_path, lines):
    """A run whose evaluations.csv is ``lines``, resumed: (run, evaluated batches, notices, original text)."""
    run = new_run(tmp_path, "run")
    original = "".join(lines)
    (run.path / EVALUATIONS).write_text(original)
    recorder = Recorder()
    with pytest.warns(Notice) as notices:
        train(run, CONFIG, recorder)
    return run, [it for it, _ in recorder.calls], [str(w.message) for w in notices], original


def set_aside(run: Run) -> list[dict]:
    with open(run.path / SET_ASIDE, newline="") as fh:
        return list(csv.DictReader(fh))


def test_a_bad_line_in_the_first_batch_costs_that_batch_only(tmp_path, reference):
    lines, pareto = reference
    broken = lines[:3] + ["0,0.5,0.25\n"] + lines[4:]  # row 3 of batch 0 lost fields
    run, evaluated, notices, original = resume(tmp_path, broken)
    assert evaluated == [0]  # batches 1 and 2 are kept, not wiped
    assert (run.path / EVALUATIONS).read_text() == "".join(lines) and (run.path / PARETO).read_text() == pareto
    assert (run.path / f"{EVALUATIONS}.orig-1").read_text() == original  # the file as it was
    rows = set_aside(run)
    assert [(r["line"], r["file"]) for r in rows] == [("2", f"{EVALUATIONS}.orig-1"), ("3", f"{EVALUATIONS}.orig-1"),
                                                      ("4", f"{EVALUATIONS}.orig-1"), ("5", f"{EVALUATIONS}.orig-1")]
    assert rows[2]["reason"] == "has 3 fields, expected 9" and rows[2]["text"] == "0,0.5,0.25"
    assert all(r["reason"] == "batch 0 is incomplete (3 of 4 rows), so it is evaluated again" for r in rows[:2] + rows[3:])
    (note,) = notices
    assert re.search(rf"4 rows of \S*{EVALUATIONS} set aside in {SET_ASIDE}: 3 rows: batch 0 is incomplete .*; "
                     rf"line 4: has 3 fields, expected 9; the file as it was is kept as {EVALUATIONS}.orig-1", note), note


def test_batches_out_of_order_are_used_and_rewritten_in_order(tmp_path, reference):
    lines, pareto = reference
    shuffled = lines[:1] + lines[7:11] + lines[1:5] + lines[5:7]  # batch 2, then 0, then 1
    run, evaluated, notices, original = resume(tmp_path, shuffled)
    assert evaluated == []  # every batch was there
    assert (run.path / EVALUATIONS).read_text() == "".join(lines) and (run.path / PARETO).read_text() == pareto
    assert (run.path / f"{EVALUATIONS}.orig-1").read_text() == original
    assert not (run.path / SET_ASIDE).exists()
    assert len(notices) == 1 and "were out of order and are rewritten in order" in notices[0]


def test_a_second_copy_of_a_batch_and_unreadable_rows_are_set_aside(tmp_path, reference):
    lines, pareto = reference
    damaged = lines[:8] + lines[5:7] + ["1,abc,0.1,0.2,0.3,0.5,1.0,0.5,7.0\n", "9,0.1,0.1,0.2,0.3,0.5,1.0,0.5,7.0\n",
                                        "2,5.0,0.1,0.2,0.3,0.5,1.0,0.5,7.0\n"]  # batch 2 lost; 2 writers; junk
    run, evaluated, notices, _ = resume(tmp_path, damaged)
    assert evaluated == [2]
    assert (run.path / EVALUATIONS).read_text() == "".join(lines) and (run.path / PARETO).read_text() == pareto
    reasons = {r["line"]: r["reason"] for r in set_aside(run)}
    assert reasons == {"8": "batch 2 is incomplete (1 of 4 rows), so it is evaluated again",
                       "9": "a further row of batch 1, which already has its 2 rows",
                       "10": "a further row of batch 1, which already has its 2 rows",
                       "11": "S.x is not a number: 'abc'",
                       "12": "batch 9 is beyond the budget (batches 0-2)",
                       "13": "S.x = 5.0 is outside its bounds [0, 1]"}
    assert "6 rows of" in notices[0]


def test_a_row_cut_short_by_a_kill_is_reported(tmp_path, reference):
    lines, _ = reference
    run, evaluated, notices, original = resume(tmp_path, lines[:9] + [lines[9][:12]])  # a kill mid-write
    assert evaluated == [2]
    assert (run.path / EVALUATIONS).read_text() == "".join(lines)
    assert {r["reason"] for r in set_aside(run)} == {
        "batch 2 is incomplete (2 of 4 rows), so it is evaluated again",
        "cut short (no line end: the run was stopped while writing it)"}
    assert "3 rows of" in notices[0] and (run.path / f"{EVALUATIONS}.orig-1").read_text() == original


def test_non_finite_objectives_are_results_kept_and_reported(tmp_path, reference):
    lines, _ = reference
    fields = lines[6].rstrip("\n").split(",")
    fields[3] = "nan"  # the first objective of batch 1's second row: a diverged world
    fields[4] = "-inf"
    diverged = lines[:6] + [",".join(fields) + "\n"] + lines[7:]
    run, evaluated, notices, _ = resume(tmp_path, diverged)
    assert evaluated == []  # a finished batch: never evaluated again
    assert (run.path / EVALUATIONS).read_text() == "".join(diverged)  # nothing rewritten
    assert not list(run.path.glob("*.orig-*")) and not (run.path / SET_ASIDE).exists()
    ev = run.evaluations()
    assert math.isnan(ev.objectives[5, 0]) and ev.objectives[5, 1] == -math.inf
    assert notices == [f"1 row of {run.path / EVALUATIONS} (batch 1) has non-finite objectives (a world diverged); "
                       f"kept as results"]


def test_a_second_resume_keeps_every_earlier_original(tmp_path, reference):
    lines, _ = reference
    run, _, _, first = resume(tmp_path, lines[:3] + ["junk\n"] + lines[4:])
    second = "".join(lines[:9] + ["2,0.1"])
    (run.path / EVALUATIONS).write_text(second)
    with pytest.warns(Notice):
        train(run, CONFIG, Recorder())
    assert (run.path / f"{EVALUATIONS}.orig-1").read_text() == first
    assert (run.path / f"{EVALUATIONS}.orig-2").read_text() == second
    files = {r["file"] for r in set_aside(run)}
    assert files == {f"{EVALUATIONS}.orig-1", f"{EVALUATIONS}.orig-2"}
    np.testing.assert_array_equal(run.evaluations().iteration, [0] * 4 + [1] * 2 + [2] * 4)


def _legacy(lines: list[str]) -> list[str]:
    """The same rows as a run written before contact forces were measured writes them: one force
    column, max_force (the commanded force), where the contact forces now stand."""
    out = [lines[0].replace("peak_contact_force,mean_contact_force,peak_commanded_force", "max_force")]
    for line in lines[1:]:
        fields = line.rstrip("\n").split(",")
        out.append(",".join(fields[:-3] + fields[-1:]) + "\n")
    return out


def test_a_run_from_before_contact_forces_resumes_with_them_unknown(tmp_path, reference):
    lines, _ = reference
    assert lines[0].rstrip().endswith("success_rate,peak_contact_force,mean_contact_force,peak_commanded_force")
    old = _legacy(lines[:7])  # batches 0 and 1 finished
    run, evaluated, notices, original = resume(tmp_path, old)
    assert evaluated == [2]  # the finished batches are kept
    text = (run.path / EVALUATIONS).read_text().splitlines(keepends=True)
    assert text[0] == lines[0] and text[7:] == lines[7:]  # the new columns; batch 2 as uninterrupted
    for new, ref in zip(text[1:7], lines[1:7]):
        new_fields, ref_fields = new.rstrip().split(","), ref.rstrip().split(",")
        assert new_fields[-3:-1] == ["nan", "nan"]  # not measured then
        assert new_fields[:-3] + new_fields[-1:] == ref_fields[:-3] + ref_fields[-1:]
    assert (run.path / f"{EVALUATIONS}.orig-1").read_text() == original
    (note,) = notices
    assert "written before contact forces were measured" in note and "6 rows" in note and "peak_commanded_force" in note
    # evaluate and select read such files too (pareto.csv as it was written then)
    (run.path / PARETO).write_text("".join(_legacy((run.path / PARETO).read_text().splitlines(keepends=True))))
    front = run.front(CONFIG)
    assert len(front) and np.isnan(front.peak_contact_force).any()
