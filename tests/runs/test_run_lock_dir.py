"""The writer's lock cannot be sidestepped by deleting ``.lock``: the
run directory itself is locked, so a second resume is refused while the first holds the run,
whether the holder is another process or this one, and whether ``.lock`` is there or not."""

import subprocess
import sys
import textwrap

import pytest

from cli_helpers import error_line, invoke, snapshot, subprocess_env
from explore_runs import make_push_run
from mjxskill.errors import RunError
from mjxskill.runs.run_lock import lock_run


def test_a_second_resume_is_refused_after_the_lock_file_was_deleted(tmp_path, capsys):
    run = make_push_run(tmp_path / "push-0")
    with lock_run(run.path):
        (run.path / ".lock").unlink()  # "it looks stale"
        before = snapshot(run.path)
        code, err = invoke(capsys, "train", "push", "--resume", run.path)
        line = error_line(code, err, "train", str(run.path), "is being written by another process")
        assert ".lock file was removed" in line
        assert snapshot(run.path) == before and not (run.path / ".lock").exists()  # nothing written, not even .lock
    lock_run(run.path).release()  # free again once the holder let go


def test_a_lock_held_by_another_process_survives_deleting_its_file(tmp_path):
    run = make_push_run(tmp_path / "push-0")
    holder = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import sys, time
        from mjxskill.runs.run_lock import lock_run
        lock = lock_run({str(run.path)!r})
        print("locked", flush=True)
        sys.stdin.readline()
        """)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=subprocess_env())
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(RunError, match=f"pid {holder.pid} on"):  # the holder says who it is
            lock_run(run.path)
        (run.path / ".lock").unlink()
        with pytest.raises(RunError, match="is being written by another process"):
            lock_run(run.path)
        assert not (run.path / ".lock").exists()
    finally:
        holder.communicate("\n", timeout=60)
    with lock_run(run.path):  # the holder ended: the run is free, .lock written again
        assert (run.path / ".lock").exists()
