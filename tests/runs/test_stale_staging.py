"""A run or experiment directory killed while it was being created leaves a staging folder
``.<name>.<host>.<pid>.<hex>.creating``; the next creation beside it removes those of processes
of this host that no longer run, and nothing else."""

import os
import signal
import subprocess
import sys
import textwrap

from cli_helpers import subprocess_env
from explore_runs import make_push_run
from mjxskill.runs.run_dir import _this_host

KILLED_WHILE_CREATING = textwrap.dedent("""
    import os, signal, sys
    from pathlib import Path
    from mjxskill.runs.run_dir import created_whole

    with created_whole(Path(sys.argv[1]), "run directory") as staging:
        (staging / "config.yaml").write_text("half written")
        print(staging.name, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)
""")


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_a_creation_killed_with_sigkill_is_cleaned_at_the_next_one(tmp_path):
    runs = tmp_path / "runs"
    done = subprocess.run([sys.executable, "-c", KILLED_WHILE_CREATING, str(runs / "push-3")], capture_output=True, text=True,
                          env=subprocess_env(), timeout=120)
    assert done.returncode == -signal.SIGKILL, done.stderr
    left = runs / done.stdout.strip()
    assert left.is_dir() and left.name.startswith(f".push-3.{_this_host()}.")
    make_push_run(runs / "push-4")
    assert sorted(p.name for p in runs.iterdir()) == ["push-4"]


def test_only_staging_folders_of_dead_processes_of_this_host_are_removed(tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    dead, host = _dead_pid(), _this_host()
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("the user's\n")
    stale = [f".push-1.{host}.{dead}.0123abcd.creating", f".push-2.{dead}.89abcdef.creating"]  # the second: before hosts were named
    kept = [f".push-5.{host}.{os.getpid()}.0123abcd.creating",  # a creation under way
            f".push-6.other-host.{dead}.0123abcd.creating",     # another machine's (a shared file system)
            ".notes.creating", "push-0"]
    for name in stale + kept:
        (runs / name).mkdir()
        (runs / name / "config.yaml").write_text("x")
    (runs / f".push-7.{host}.{dead}.00000000.creating").symlink_to(outside)  # a link: neither followed nor removed
    make_push_run(runs / "push-8")
    names = {p.name for p in runs.iterdir()}
    assert not names & set(stale)
    assert set(kept) | {f".push-7.{host}.{dead}.00000000.creating", "push-8"} <= names
    assert (outside / "keep.txt").read_text() == "the user's\n"


def test_an_output_set_aside_by_a_killed_replacement_goes_back_where_nothing_took_its_place(tmp_path):
    """A folder replaced by a folder is set aside (``.replaced``) before the new one is renamed in;
    killed between the two, the old one is renamed back by the next write beside it, not removed."""
    from mjxskill.runs.atomic_write import remove_stale_staging

    pid = _dead_pid()
    old = tmp_path / f".frames.{_this_host()}.{pid}.0123abcd.replaced"
    old.mkdir()
    (old / "frame_0000.png").write_bytes(b"the user's frame")
    new = tmp_path / f".frames.{_this_host()}.{pid}.4567cdef.creating"
    new.mkdir()
    remove_stale_staging(tmp_path)
    assert (tmp_path / "frames" / "frame_0000.png").read_bytes() == b"the user's frame"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames"]
    # where the replacement did arrive, the set-aside one is stale and goes
    old.mkdir()
    remove_stale_staging(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames"]
