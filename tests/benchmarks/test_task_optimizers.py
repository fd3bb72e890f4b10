"""``benchmarks/task_optimizers.py --quick``: one tiny run per task and method, the shared
warm-up, the hypervolume about the union of the warm-ups against a closed-form 2-D sweep, and a
benchmark started again resuming an unfinished run to the same rows."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import optuna  # noqa: E402,F401  (the test extra's; the benchmark imports it)

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import task_optimizers as bench  # noqa: E402
from mjxskill.runs.run_dir import EVALUATIONS, Run  # noqa: E402
from mjxskill.scenario import load_scenario  # noqa: E402
from mjxskill.task import plan_task  # noqa: E402

METHODS = ("mjxskill.gp", "optuna-nsga2", "optuna-tpe", "random")


def hypervolume_2d(rewards: np.ndarray, ref: np.ndarray) -> float:
    """Area dominated by ``rewards`` (n, 2, larger is better) above ``ref``: a sweep over the
    first objective, best first."""
    pts = rewards[np.all(rewards > ref, axis=1)]
    area, height = 0.0, ref[1]
    for x, y in sorted(map(tuple, pts), reverse=True):
        if y > height:
            area += (x - ref[0]) * (y - height)
            height = y
    return area


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    bench.main(["--quick", "--out", str(out)])
    return out, [json.loads(line) for line in (out / bench.JSONL).read_text().splitlines()]


def test_one_line_per_task_and_method_with_the_runs_settings(quick):
    _, rows = quick
    assert [(r["task"], r["method"], r["seed"]) for r in rows] == [(t, m, 0) for t in ("push", "peg") for m in METHODS]
    for r in rows:
        assert (r["budget"], r["batch_size"], r["n_init"], r["worlds"]) == (12, 6, 6, 1)
        assert r["evaluations"] == [6, 12] and len(r["hypervolume_history"]) == 2
        assert len(r["ask_seconds"]) == 1 and r["ask_seconds"][0] >= 0  # one proposal after the warm-up


def test_methods_share_the_warm_up_and_the_reference_and_the_hypervolume_is_the_swept_area(quick):
    _, rows = quick
    for task in ("push", "peg"):
        mine = [r for r in rows if r["task"] == task]
        evs = {r["method"]: Run(r["run_dir"]).evaluations() for r in mine}
        for ev in evs.values():  # the same warm-up rows, then each method its own
            np.testing.assert_array_equal(ev.params[:6], evs["random"].params[:6])
        assert len({ev.params[6:].tobytes() for ev in evs.values()}) == len(METHODS)
        # the reference: worst warm-up reward of each objective minus 10 % of the warm-up range
        warm = np.concatenate([ev.objectives[:6] for ev in evs.values()])
        ref = warm.min(axis=0) - 0.1 * (warm.max(axis=0) - warm.min(axis=0))
        for r in mine:
            np.testing.assert_allclose(r["reference"], ref, rtol=1e-12)
            y = evs[r["method"]].objectives
            assert r["hypervolume"] == pytest.approx(hypervolume_2d(y, ref), rel=1e-9)
            assert r["hypervolume_history"][0] == pytest.approx(hypervolume_2d(y[:6], ref), rel=1e-9)


def test_the_planning_files_are_written_once_per_task_beside_its_runs(quick):
    out, _ = quick
    planning = ("domain.pddl", "problem.pddl", "plan.txt", "bt.txt")
    for task in ("push", "peg"):
        where = out / "runs" / task
        assert sorted(p.relative_to(where).as_posix() for name in planning for p in where.rglob(name)) == sorted(planning)
        task_plan = plan_task(load_scenario(task))
        assert (where / "domain.pddl").read_text().rstrip("\n") == task_plan.domain_pddl.rstrip("\n")
        assert (where / "plan.txt").read_text() == f"; goal: {task_plan.goal}\n" + "\n".join(task_plan.plan) + "\n"


def test_started_again_it_resumes_the_unfinished_run_and_keeps_the_finished(quick):
    out, rows = quick
    cut = out / "runs" / "push" / "optuna-tpe" / "seed-0" / EVALUATIONS
    full = cut.read_text()
    others = {p: p.stat().st_mtime_ns for p in (out / "runs").rglob(EVALUATIONS) if p != cut}
    cut.write_text("".join(full.splitlines(keepends=True)[:7]))  # as a kill after the warm-up leaves it
    bench.main(["--quick", "--out", str(out)])
    assert cut.read_text() == full
    assert {p: p.stat().st_mtime_ns for p in others} == others  # the finished runs: not evaluated again
    again = [json.loads(line) for line in (out / bench.JSONL).read_text().splitlines()]
    drop = lambda r: {k: v for k, v in r.items() if k != "ask_seconds"}  # noqa: E731  (wall times differ)
    assert [drop(r) for r in again] == [drop(r) for r in rows]


def test_a_later_invocation_keeps_the_finished_runs_of_other_methods_and_the_lines_of_other_tasks(quick):
    """A second invocation into the same folder (another method, another task) rewrites the
    file with every finished run in it, not only its own: a task's line from another file is
    kept as written, and the runs of the methods not asked for are rebuilt from their
    directories about the same reference."""
    out, rows = quick
    elsewhere = {**rows[0], "task": "pick-place", "hypervolume": 1.5}
    path = out / bench.JSONL
    path.write_text(path.read_text() + json.dumps(elsewhere) + "\n")
    again = bench.main(["--quick", "--methods", "random", "--out", str(out)])  # every run finished: recorded again
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    assert lines == json.loads(json.dumps(again)) and lines[0] == elsewhere
    drop = lambda r: {k: v for k, v in r.items() if k != "ask_seconds"}  # noqa: E731
    key = lambda r: (r["task"], r["method"], r["seed"])  # noqa: E731
    assert sorted(map(drop, lines[1:]), key=key) == sorted(map(drop, rows), key=key)
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))


def test_report_reads_the_file_and_a_bad_file_is_one_error_line(quick, tmp_path):
    out, rows = quick
    table = bench.report(bench.read_rows([out / bench.JSONL]))
    assert "| push | mjxskill.gp | 1 | 12 x 1 |" in table and "| peg | optuna-tpe |" in table
    bad = tmp_path / "bad.jsonl"
    bad.write_text(json.dumps(rows[0]) + "\n{not json\n")
    done = subprocess.run([sys.executable, bench.__file__, "--report", str(bad)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines() == [f"task_optimizers.py: error: --report {bad} line 2: not JSON "
                                                 "(Expecting property name enclosed in double quotes)"]


def test_report_puts_rows_about_different_reference_points_on_the_lowest(quick, tmp_path):
    out, rows = quick
    # a run of another seed, written by another invocation: its warm-up set a higher reference
    own = np.array(rows[0]["reference"])
    other = {**rows[0], "seed": 99, "front": [(own + [3.0, 5.0]).tolist(), (own + [4.0, 2.0]).tolist()],
             "reference": (own + 1.0).tolist(), "hypervolume": 3.0, "run_dir": str(tmp_path / "gone")}
    moved = tmp_path / "moved.jsonl"
    moved.write_text(json.dumps(other) + "\n")
    task = [r for r in bench.read_rows([out / bench.JSONL, moved]) if r["task"] == rows[0]["task"]]
    common = bench.on_common_reference(task)
    assert all(r["reference"] == own.tolist() for r in common)
    # about the lower point, two boxes by hand: 3 x 5 and 4 x 2, less their 3 x 2 overlap
    assert common[-1]["hypervolume"] == pytest.approx(15.0 + 8.0 - 6.0)
    assert "hypervolume_history" not in common[-1]  # its directory is gone: no history about the lower point
    assert [r["hypervolume"] for r in common[:-1]] == [r["hypervolume"] for r in task[:-1]]  # already about it
    assert "Final hypervolumes about push: the lowest of the rows' 2 reference points" in bench.report(
        bench.read_rows([out / bench.JSONL, moved]))


def test_report_refuses_a_run_named_twice(quick):
    out, _ = quick
    with pytest.raises(bench.UserError, match="appear in more than one line"):
        bench.report(bench.read_rows([out / bench.JSONL, out / bench.JSONL]))


def test_the_pick_is_the_validated_best_and_is_checked_again_in_fresh_worlds(quick):
    _, rows = quick
    for r in rows:
        doc = json.loads((Path(r["run_dir"]) / "evaluation" / "validation.json").read_text())
        success, seconds = np.array(doc["success"]), np.array(doc["seconds"])
        i = doc["params"].index(r["pick_params"])
        # the most successful contender, of equal ones the fastest (as an experiment picks)
        assert success[i] == success.max() == r["pick_validation_success"]
        assert seconds[i] == seconds[success == success.max()].min()
        known = 4 if r["task"] == "push" else 5
        assert r["pick_validation_worlds"] == known and r["pick_fresh_worlds"] == known
        assert r["pick_fresh_success"] * known == pytest.approx(round(r["pick_fresh_success"] * known))
        stored = json.loads((Path(r["run_dir"]) / bench.PICK).read_text())
        assert stored["params"] == r["pick_params"] and stored["seed"] == bench.FRESH_SEED


def test_a_history_about_another_reference_is_computed_again_from_the_run_directory(quick):
    out, rows = quick
    row = rows[0]
    lower = np.array(row["reference"]) - [2.0, 3.0]
    moved = {**row, "seed": 99, "reference": lower.tolist()}  # another seed's row, about a lower point
    common = bench.on_common_reference([row, moved])
    y = Run(row["run_dir"]).evaluations().objectives
    assert common[0]["evaluations"] == [6, 12]
    assert common[0]["hypervolume_history"] == pytest.approx([hypervolume_2d(y[:e], lower) for e in (6, 12)], rel=1e-9)


def test_the_report_gives_each_methods_median_at_fractions_of_the_budget(quick):
    out, rows = quick
    rows_read = bench.read_rows([out / bench.JSONL])
    lines = bench.budget_fractions({task: bench.on_common_reference([r for r in rows_read if r["task"] == task])
                                    for task in ("push", "peg")})
    for r in rows:  # one seed: the median is the run's history, interpolated at 3, 6, 9 and 12 evaluations
        h = r["hypervolume_history"]
        expected = [h[0], h[0], (h[0] + h[1]) / 2, h[1]]
        assert f"| {r['task']} | {r['method']} | 1 | " + " | ".join(f"{v:.4g}" for v in expected) + " |" in lines
    trailing = [line for line in lines if " below " in line]
    for task in ("push", "peg"):
        ours = next(r["hypervolume_history"] for r in rows if r["task"] == task and r["method"] == "mjxskill.gp")
        for fraction, k in (("100 %", 1),):
            ahead = [r["method"] for r in rows if r["task"] == task and r["hypervolume_history"][k] > ours[k]]
            said = [line for line in trailing if line.startswith(f"{task} at {fraction}:")]
            assert said == ([f"{task} at {fraction}: mjxskill.gp's median below {', '.join(ahead)}"] if ahead else [])


def test_optimizer_options_reach_our_runs_only(tmp_path):
    out = tmp_path / "bench"
    rows = bench.main(["--quick", "--tasks", "push", "--methods", "mjxskill.gp,random", "--optimizer-option",
                       "single_direction_share=0", "--out", str(out)])
    assert {r["method"]: r["optimizer_options"] for r in rows}["random"] == {}
    ours = next(r for r in rows if r["method"] == "mjxskill.gp")
    assert ours["optimizer_options"]["single_direction_share"] == 0.0
    assert Run(ours["run_dir"]).config().optimizer_options["single_direction_share"] == 0.0
    done = subprocess.run([sys.executable, bench.__file__, "--optimizer-option", "n_raw=lots"], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 2 and "n_raw" in done.stderr and "Traceback" not in done.stderr
