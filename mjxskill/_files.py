"""The one way a file the user hands over is read (a scenario, a skill library, a run's files):
only a regular file, and only after that is known.

``open`` on a FIFO blocks until a writer comes, forever (a FIFO given as a scenario, or planted in
a run's place of ``evaluations.csv``, hung the command); a character device (``/dev/zero``) never
ends. ``read_regular`` opens without blocking (``O_NONBLOCK``: a FIFO's open returns at once),
asks the open file what it is (``fstat``: no race between a check and the open) and reads only a
regular file; anything else is ``NotRegularFile``, an ``OSError`` whose ``strerror`` names what
the path is, so that every reader's existing "cannot read PATH (why)" error says it. Imports
nothing of mjxskill: every stage may read through it."""

from __future__ import annotations

import errno
import os
import stat

KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
         (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


class NotRegularFile(OSError):
    """A path that names something other than a regular file; never opened for reading."""


def kind_of(mode: int) -> str:
    return next((name for test, name in KINDS if test(mode)), "something else")


def not_regular(mode: int) -> str:
    """What every refusal says of a path of ``mode``: "is not a regular file but a FIFO (named pipe)"."""
    return f"is not a regular file but {kind_of(mode)}"


# Opening without blocking: a FIFO's open returns at once instead of waiting for a writer.
OPEN_FLAGS = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)


def read_regular(path, limit: int | None = None) -> bytes:
    """The bytes of the regular file ``path`` (the first ``limit + 1`` at most when ``limit`` is
    given, so that a caller sees a file over its bound). NotRegularFile for a FIFO, device,
    socket or directory, without reading from it; other OSErrors as ``open`` raises them."""
    try:
        fd = os.open(path, OPEN_FLAGS)
    except IsADirectoryError:
        raise NotRegularFile(errno.EISDIR, "is not a regular file but a directory", str(path)) from None
    return read_open(fd, path, limit)


def is_regular(path, error: type[Exception] | None = None) -> bool:
    """Whether a regular file is at ``path`` (a link followed, as ``Path.is_file``): False when
    nothing is there; when something else is (a FIFO, a device, a folder), ``error`` (an exception
    class taking the message) naming the path and what it is, or NotRegularFile without one. What a
    reader asks before it reads a file that may be missing: a FIFO is never taken for a missing
    file (a run whose ``config.yaml`` was a FIFO was "not a run directory")."""
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return False
    except OSError:  # a name too long, a loop of links: the read that follows says it
        return False
    if stat.S_ISREG(mode):
        return True
    what = not_regular(mode)
    if error is None:
        raise NotRegularFile(errno.EINVAL, what, str(path))
    raise error(f"{path} {what}; mjxskill reads only regular files: remove it or put the file there")


def read_open(fd: int, path, limit: int | None = None) -> bytes:
    """What ``read_regular`` returns, from ``fd`` opened with ``OPEN_FLAGS`` (and whatever else
    the caller needs, as ``O_NOFOLLOW`` below a folder's descriptor), ``path`` naming it in the
    error; ``fd`` is closed either way."""
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise NotRegularFile(errno.EINVAL, not_regular(mode), str(path))
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=True) as fh:
            fd = -1
            return fh.read() if limit is None else fh.read(limit + 1)
    finally:
        if fd >= 0:
            os.close(fd)


__all__ = ["OPEN_FLAGS", "NotRegularFile", "is_regular", "kind_of", "not_regular", "read_open", "read_regular"]
