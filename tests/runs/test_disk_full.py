"""A full disk or a read-only file system mid-run: one ``error:`` line naming the path, exit
code 1 (the machine's fault, not the input's), nothing finished lost, no temporary file left,
and the command run again goes on. The disk is made "full" or read-only by making the file
system calls the writers use fail with ENOSPC or EROFS (a real full or read-only file system
needs a mount the test machine does not allow): at the first write and at a later one, for
``train``, ``select --out`` and ``plan --export``."""

import errno
import os
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import invoke, snapshot
from explore_runs import make_push_run
from mjxskill.runs.run_dir import Run
from push_runs import push_run

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


# -- a read-only file system or a full disk at any write of a command ------------------------------
def _where(path, dir_fd=None) -> str:
    """The absolute path an ``os`` call names (a name in the folder ``dir_fd``: joined to it)."""
    path = os.fsdecode(os.fspath(path))
    if dir_fd is not None and not os.path.isabs(path):
        path = os.path.join(os.readlink(f"/proc/self/fd/{dir_fd}"), path)
    return os.path.abspath(path)


def failing_disk(monkeypatch, root, code: int, at: int, calls=("open", "write")) -> list:
    """From the ``at``-th write below ``root`` on, each fails with ``OSError(code)``: a file opened
    for writing (``os.open``, ``open``), a folder made (``os.mkdir``) when "open" is in ``calls``,
    bytes written to a file (``os.write``) when "write" is. Returns the list of writes seen."""
    import builtins
    import io
    import stat

    seen: list[str] = []
    real_open, real_mkdir, real_write, real_io_open = os.open, os.mkdir, os.write, io.open

    def fault(where: str) -> None:
        if where == str(root) or where.startswith(str(root) + os.sep):
            seen.append(where)
            if len(seen) > at:
                raise OSError(code, os.strerror(code), where)

    def os_open(path, flags, mode=0o777, *, dir_fd=None):
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
            fault(_where(path, dir_fd))
        return real_open(path, flags, mode, dir_fd=dir_fd)

    def mkdir(path, mode=0o777, *, dir_fd=None):
        fault(_where(path, dir_fd))
        return real_mkdir(path, mode, dir_fd=dir_fd)

    def write(fd, data):
        if stat.S_ISREG(os.fstat(fd).st_mode):
            fault(os.readlink(f"/proc/self/fd/{fd}"))
        return real_write(fd, data)

    def io_open(file, mode="r", *args, **kwargs):
        if isinstance(file, (str, bytes, os.PathLike)) and set(mode) & set("wax+"):
            fault(_where(file))
        return real_io_open(file, mode, *args, **kwargs)

    if "open" in calls:
        monkeypatch.setattr(os, "open", os_open)
        monkeypatch.setattr(os, "mkdir", mkdir)
        monkeypatch.setattr(io, "open", io_open)
        monkeypatch.setattr(builtins, "open", io_open)
    if "write" in calls:
        monkeypatch.setattr(os, "write", write)
    return seen


def machine_fault_line(code, stderr, prog, errno_, root) -> str:
    """Exit 1 and one ``prog: error:`` line saying what the system said and naming a path below ``root``."""
    assert code == 1, stderr
    assert "Traceback" not in stderr, stderr
    errors = [line for line in stderr.splitlines() if ": error:" in line]
    assert len(errors) == 1 and errors[0].startswith(f"mjxskill.{prog}: error: {os.strerror(errno_)} ({root}"), stderr
    return errors[0]


def half_written(folder) -> list[str]:
    """Stagings, temporary files and empty files (the lock's aside) below ``folder``."""
    return sorted(str(p) for p in Path(folder).rglob("*") if p.name.endswith((".tmp", ".creating", ".replaced"))
                  or (p.is_file() and p.stat().st_size == 0 and p.name != ".lock"))


TRAIN = ["push", "--engine", "native", "--budget", 4, "--batch-size", 2, "--init", 2, "--worlds", 1,
         "--episode-seconds", 0.2, "--workers", 1, "--quiet"]
FAULTS = [(errno.EROFS, 0, ("open",)), (errno.ENOSPC, 0, ("write",)), (errno.ENOSPC, 3, ("open",)),
          (errno.EROFS, 1, ("write",))]


@pytest.mark.parametrize("errno_, at, calls", FAULTS)
def test_train_on_a_read_only_or_full_disk_is_one_fault_line_and_runs_again(tmp_path, capsys, monkeypatch, errno_, at,
                                                                            calls):
    run = tmp_path / "run"
    seen = failing_disk(monkeypatch, tmp_path, errno_, at, calls)
    code, err = invoke(capsys, "train", *TRAIN, "--out", run)
    monkeypatch.undo()
    assert len(seen) > at  # the fault was met
    machine_fault_line(code, err, "train", errno_, tmp_path)
    assert half_written(tmp_path) == []
    if run.exists():  # what was written is whole: the finished batches are read as they are
        assert Run(run).batches(Run(run).config()).rejected == []
    code, err = invoke(capsys, "train", *(["push", "--resume", run, "--workers", 1, "--quiet"] if run.exists()
                                          else [*TRAIN, "--out", run]))
    assert code == 0, err
    config = Run(run).config()
    assert len(Run(run).evaluations(config)) == config.training_rows and half_written(tmp_path) == []


@pytest.mark.parametrize("errno_", [errno.EROFS, errno.ENOSPC])
@pytest.mark.parametrize("at", [0, 1])
@pytest.mark.parametrize("calls", [("open",), ("write",)])
@pytest.mark.parametrize("command", ["select", "plan"])
def test_an_export_on_a_read_only_or_full_disk_writes_nothing_and_runs_again(tmp_path_factory, capsys, monkeypatch, command,
                                                                             calls, at, errno_):
    base = tmp_path_factory.mktemp("export")
    out = base / "out" / "nested"  # folders made for it, removed again
    if command == "select":
        run = make_push_run(base / "push-0")
        args = ["select", run.path, "--pick", 0, "--no-render", "--out", out]
    else:
        args = ["plan", "push", "--export", out]
    seen = failing_disk(monkeypatch, base / "out", errno_, at, calls)
    code, err = invoke(capsys, *args)
    monkeypatch.undo()
    assert len(seen) > at
    machine_fault_line(code, err, command, errno_, base / "out")
    assert not (base / "out").exists()  # nothing of the export, no folder made for it
    code, err = invoke(capsys, *args)
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == (["parameters.json", "parameters.yaml"] if command == "select"
                                                     else ["domain.pddl", "problem.pddl"])
    assert half_written(base) == []
