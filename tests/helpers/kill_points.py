"""Kill -9 at any point of a command's writers: every file-system call that changes something
below a folder (a file opened for writing, bytes written or forced to disk, a file cut, replaced,
renamed, linked or removed, a folder made or removed) is counted, and a command run with
``killed_at(k)`` kills itself with SIGKILL right before the ``k``-th. A reference run counts
them (``counting``), so that the kill points can be chosen over the whole run (``kill_points``:
the windows where a kill lost a file's last update are right after an append and at the end)."""

from __future__ import annotations

import builtins
import contextlib
import io
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from cli_helpers import HELPERS, ROOT, subprocess_env

# the os calls that change a folder's content: name -> (how the path is found: "path" (argument
# 0, with dir_fd) or "fd" (argument 0 is a descriptor), whether a write flag is needed)
CALLS = {"open": "path", "mkdir": "path", "rmdir": "path", "unlink": "path", "replace": "path", "rename": "path",
         "link": "path", "write": "fd", "fsync": "fd", "ftruncate": "fd"}
WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND


def _where(path, dir_fd=None) -> str:
    path = os.fsdecode(os.fspath(path))
    if dir_fd is not None and not os.path.isabs(path):
        path = os.path.join(os.readlink(f"/proc/self/fd/{dir_fd}"), path)
    return os.path.abspath(path)


@contextlib.contextmanager
def counting(root: Path, kill_at: int | None = None):
    """Counts the changes below ``root`` in the block (yields the list of (call, path) seen);
    with ``kill_at``, SIGKILL right before the change of that number (1: the first)."""
    root = str(Path(root).resolve())
    seen: list[tuple[str, str]] = []
    real = {name: getattr(os, name) for name in CALLS}
    real_io_open = io.open

    def change(name: str, where: str) -> None:
        if where == root or where.startswith(root + os.sep):
            seen.append((name, where))
            if kill_at is not None and len(seen) >= kill_at:
                os.kill(os.getpid(), signal.SIGKILL)

    def wrapped(name: str):
        call = real[name]

        def by_path(path, *args, **kwargs):
            if name != "open" or (args and args[0] & WRITE_FLAGS):
                change(name, _where(path, kwargs.get("dir_fd", kwargs.get("src_dir_fd"))))
            return call(path, *args, **kwargs)

        def by_fd(fd, *args, **kwargs):
            with contextlib.suppress(OSError):
                change(name, os.readlink(f"/proc/self/fd/{fd}"))
            return call(fd, *args, **kwargs)

        return by_fd if CALLS[name] == "fd" else by_path

    def io_open(file, mode="r", *args, **kwargs):
        if isinstance(file, (str, bytes, os.PathLike)) and set(mode) & set("wax+"):
            change("open", _where(file))
        return real_io_open(file, mode, *args, **kwargs)

    try:
        for name in CALLS:
            setattr(os, name, wrapped(name))
        io.open = builtins.open = io_open
        yield seen
    finally:
        for name, call in real.items():
            setattr(os, name, call)
        io.open = builtins.open = real_io_open


KILLED = textwrap.dedent("""
    import sys
    sys.path.insert(0, {helpers!r})
    from pathlib import Path
    from kill_points import counting
    root, kill_at, module, *args = sys.argv[1:]
    import importlib
    main = importlib.import_module(f"mjxskill.cli.{{module}}").main
    with counting(Path(root), int(kill_at)):
        code = main(args)
    sys.exit(code)
""").format(helpers=str(HELPERS))


def killed_at(kill_at: int, root: Path, module: str, *args) -> subprocess.CompletedProcess:
    """``python -m mjxskill.<module> args`` killed with SIGKILL right before its ``kill_at``-th
    change below ``root`` (it may end before: returncode 0)."""
    return subprocess.run([sys.executable, "-c", KILLED, str(root), str(kill_at), module, *map(str, args)], cwd=ROOT,
                          env=subprocess_env(), capture_output=True, text=True, timeout=600)


def kill_points(seen: list[tuple[str, str]]) -> dict[str, int]:
    """Where to kill a run whose changes were ``seen`` (numbers as ``killed_at`` takes them): in
    the middle; right after its last append was forced to disk (the rows are kept, what follows
    them not yet: the optimizer state, the Pareto front, a chunk file's removal); and before its
    very last change."""
    appended = max(i for i, (call, _) in enumerate(seen, 1) if call == "fsync")
    return {"middle": max(2, len(seen) // 2), "after the last append": appended + 1, "last": len(seen)}


__all__ = ["counting", "kill_points", "killed_at"]
