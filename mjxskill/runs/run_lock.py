"""One writer per run directory: an exclusive ``fcntl`` lock on the directory itself and on
``RUN_DIR/.lock``.

Two ``train --resume`` of one run at once both replayed the file and both appended (6 rows for
a budget of 4). The lock is taken before the evaluations are read and held until the command
ends; a second writer fails at once with a ``RunError`` naming the holder (process id, host,
start time, command line), which the holder wrote into the lock file. The kernel releases the
lock when the holder exits, however it exits (a kill included), so a stale file never blocks.

The lock that counts is the one on the directory (``flock`` of a descriptor opened on
``RUN_DIR``): every finished run leaves its ``.lock``, which looks stale, and a user who deleted
it while a resume ran let a second resume in (both appended every later batch). Deleting the
directory deletes the run with it, so that lock cannot be sidestepped; ``.lock`` only says who
holds it (a holder of an older version locked only the file, which is still taken too).
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import socket
import sys
import time
from pathlib import Path

from mjxskill.errors import RunError, quote
from mjxskill.runs.atomic_write import DISK_FAULTS, open_nofollow
from mjxskill.runs.folders import disown_folder, own_folder

LOCK_FILE = ".lock"


class RunLock:
    """A held lock; ``release()`` (or leaving the ``with`` block) lets the next writer in."""

    def __init__(self, path: Path, fd: int, dir_fd: int):
        self._fd: int | None
        self._dir_fd: int | None  # None once released
        self.path, self._fd, self._dir_fd = path, fd, dir_fd
        # while held, every write below the run (or experiment) is reached from it, link-proof
        self._owned: Path | None = own_folder(Path(path).parent)

    def release(self) -> None:
        if self._owned is not None:
            disown_folder(self._owned)
            self._owned = None
        if self._fd is not None:
            os.close(self._fd)  # closing the descriptor drops the flock
            self._fd = None
        if self._dir_fd is not None:
            os.close(self._dir_fd)
            self._dir_fd = None

    def __enter__(self) -> "RunLock":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _cannot_lock(folder: Path, err: OSError) -> Exception:
    """Why the lock of ``folder`` cannot be taken: the OSError itself for a fault of the machine
    (a read-only file system, a full disk: the command's exit 1), else a RunError naming it."""
    if err.errno in DISK_FAULTS:
        return OSError(err.errno, err.strerror, str(Path(folder) / LOCK_FILE))
    return RunError(f"cannot lock the run directory {quote(str(folder), 200)}: {err.strerror}")


def lock_run(folder: Path) -> RunLock:
    """Takes the writer's lock of the run in ``folder``; RunError if another process holds it
    (also when it deleted the ``.lock`` file: the directory itself is locked)."""
    path = Path(folder) / LOCK_FILE
    try:
        dir_fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    except OSError as err:
        raise _cannot_lock(folder, err) from None
    try:
        fcntl.flock(dir_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as err:
        os.close(dir_fd)
        if err.errno in (errno.EWOULDBLOCK, errno.EACCES):
            raise RunError(f"{folder} is being written by another process ({_holder_of(path)}); wait for it to "
                           f"end or stop it, then run again") from None
        raise _cannot_lock(folder, err) from None
    try:
        # in the folder held: a folder swapped in between is never locked instead; a link's target would be truncated below
        fd = open_nofollow(path, os.O_RDWR | os.O_CREAT | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0), dir_fd=dir_fd)
    except RunError:
        os.close(dir_fd)
        raise
    except OSError as err:
        os.close(dir_fd)
        raise _cannot_lock(folder, err) from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as err:  # a writer of before the directory was locked: it holds only the file
        holder = _holder(fd)
        os.close(fd)
        os.close(dir_fd)
        if err.errno in (errno.EWOULDBLOCK, errno.EACCES):
            raise RunError(f"{folder} is being written by another process ({holder}); wait for it to end "
                           f"or stop it, then run again") from None
        raise _cannot_lock(folder, err) from None
    info = {"pid": os.getpid(), "host": socket.gethostname(), "since": time.strftime("%Y-%m-%d %H:%M:%S"),
            "command": " ".join([os.path.basename(sys.executable), *sys.argv])}
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
    except OSError:  # who holds the lock is a courtesy; a full disk must not stop the holder here
        pass
    return RunLock(path, fd, dir_fd)


def _holder_of(path: Path) -> str:
    """What the holder wrote about itself into ``path`` (read without following a link)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)  # a FIFO's open would wait
    except OSError:
        return f"its {LOCK_FILE} file was removed, so it cannot say who it is"
    try:
        return _holder(fd)
    finally:
        os.close(fd)


def _holder(fd: int) -> str:
    """What the holder wrote about itself (it writes right after locking: may still be empty)."""
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
        return f"pid {info['pid']} on {info['host']} since {info['since']}: {info['command']}"
    except (ValueError, KeyError, TypeError, OSError):
        return "a process that has not said who it is yet"


__all__ = ["LOCK_FILE", "RunLock", "lock_run"]
