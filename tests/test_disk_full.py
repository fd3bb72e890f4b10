"""A full disk mid-run: one ``error:`` line, exit code 1, nothing
finished lost, no temporary file left, and the command run again goes on. The disk is made
"full" by making the file system calls the run directory's writers use fail with ENOSPC (a real
full file system needs a mount the test machine does not allow)."""

import errno
import os

import numpy as np

from cli_helpers import invoke, snapshot
from explore_runs import make_push_run
from mjxskill.runs.run_dir import Run
from test_bad_input import push_run

SMALL = dict(engine="native", budget=4, batch_size=2, n_init=2, worlds=1, episode_seconds=0.2)


def full(*_args, **_kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def fault_line(code, stderr, prog):
    assert code == 1, stderr
    assert "Traceback" not in stderr, stderr
    errors = [line for line in stderr.splitlines() if ": error:" in line]
    assert len(errors) == 1 and errors[0].startswith(f"mjxskill.{prog}: error: No space left on device"), stderr
    assert "nothing finished is lost" in errors[0] and "free some space" in errors[0]
    return errors[0]


def leftovers(folder):
    return sorted(str(p) for p in folder.rglob("*") if p.name.endswith(".tmp") or ".creating" in p.name)


def test_train_on_a_full_disk_keeps_every_finished_batch_and_resumes(tmp_path, capsys, monkeypatch):
    run = push_run(tmp_path / "run", **SMALL)
    replace = os.replace

    def replace_until_full(src, dst, *args, **kwargs):  # the first batch's rows are appended, then the disk is full
        if str(dst).endswith("pareto.csv"):
            full()
        return replace(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", replace_until_full)
    code, err = invoke(capsys, "train", "push", "--resume", run.path, "--workers", 1, "--quiet")
    monkeypatch.undo()
    fault_line(code, err, "train")
    assert leftovers(tmp_path) == []
    config = run.config()
    kept = run.evaluations(config)
    assert len(kept) == 2  # the finished batch
    code, err = invoke(capsys, "train", "push", "--resume", run.path, "--workers", 1, "--quiet")
    assert code == 0, err
    done = Run(run.path).evaluations(config)
    assert len(done) == 4 and np.array_equal(done.params[:2], kept.params)
    assert leftovers(tmp_path) == []


def test_an_append_that_fails_leaves_no_part_of_the_batch(tmp_path, capsys, monkeypatch):
    run = push_run(tmp_path / "run", **SMALL)
    before = (run.path / "evaluations.csv").read_bytes()
    monkeypatch.setattr(os, "fsync", full)  # the rows were written, the disk cannot keep them
    code, err = invoke(capsys, "train", "push", "--resume", run.path, "--workers", 1, "--quiet")
    monkeypatch.undo()
    fault_line(code, err, "train")
    assert (run.path / "evaluations.csv").read_bytes() == before and leftovers(tmp_path) == []


def test_select_on_a_full_disk_leaves_no_empty_parameter_file(tmp_path, capsys, monkeypatch):
    run = make_push_run(tmp_path / "push-0")
    before = snapshot(run.path)
    monkeypatch.setattr(os, "replace", full)
    code, err = invoke(capsys, "select", run.path, "--pick", 0, "--no-render")
    monkeypatch.undo()
    fault_line(code, err, "select")
    assert leftovers(tmp_path) == []
    assert {k: v for k, v in snapshot(run.path).items() if not k.startswith("selected-")} == before
    assert not list(run.path.glob("selected-*/parameters.*"))  # no 0-byte parameters.yaml
