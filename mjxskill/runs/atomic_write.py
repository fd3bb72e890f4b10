"""Files replaced whole: a reader, or a run killed while it writes, sees the old file or the
new one, never part of one (the text goes to ``NAME.tmp`` beside it, then ``os.replace``).

A file that is a symbolic link is never written through: a link in a run directory to a file
elsewhere would have that file replaced (``refuse_link``: one RunError naming the link). Nor is
one read through when it leaves the directory: ``refuse_links_out`` walks a run or experiment
directory before a command reads it (an ``explore/`` folder, an evaluation file or a ``seed-<s>``
run linked elsewhere would be read, and written into, as the run's own); a link that stays
inside is harmless and allowed."""

from __future__ import annotations

import contextlib
import errno
import json
import os
from pathlib import Path
from typing import Callable

from mjxskill.errors import RunError


def refuse_link(path: Path) -> None:
    """Raises RunError naming ``path`` when it is a symbolic link."""
    if os.path.islink(path):
        raise RunError(f"{path} is a symbolic link (to {os.readlink(path)!r}); mjxskill writes a run's files only "
                       "in the run itself: replace the link by the file it points to, or remove it")


# Errors of the machine, not of what the user gave: a command ends on them with exit code 1
# (mjxskill.cli.run), never with the exit code 2 of bad input.
DISK_FAULTS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO, errno.EROFS})

MAX_ENTRIES = 1_000_000  # files and folders one walk looks at: a run with every frame rendered has thousands


def refuse_links_out(root: Path) -> None:
    """Raises RunError naming the first symbolic link below ``root`` (``root`` itself may be one:
    the user named it) whose target is not inside ``root``; follows no link while walking."""
    root = Path(root)
    if not root.is_dir():
        return  # "not a run directory" is said by whoever reads it
    real_root = os.path.realpath(root)
    seen = 0
    for folder, dirs, files in os.walk(root):  # os.walk lists linked folders among dirs, never enters them
        dirs.sort()
        for name in sorted(dirs + files):
            seen += 1
            if seen > MAX_ENTRIES:
                raise RunError(f"{root} holds more than {MAX_ENTRIES} files and folders; is it a run directory?")
            path = os.path.join(folder, name)
            if not os.path.islink(path):
                continue
            target = os.path.realpath(path)
            if os.path.commonpath([real_root, target]) != real_root:
                raise RunError(f"{path} is a symbolic link (to {os.readlink(path)!r}) that leaves {root}; mjxskill reads "
                               "and writes a run's files only in the run itself: replace the link by what it points "
                               "to, or remove it")


def replace_whole(path: Path, write: Callable[[Path], object]) -> None:
    """``write(tmp)`` fills ``NAME.tmp`` beside ``path``, which then replaces ``path``; RunError
    when ``path`` is a symbolic link. When writing fails (a full disk) ``path`` is unchanged and
    ``NAME.tmp`` removed."""
    refuse_link(path)
    tmp = path.with_name(path.name + ".tmp")
    if os.path.lexists(tmp):  # left by a killed writer, or a link: removed, never written through
        os.unlink(tmp)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:  # a full disk, Ctrl-C: the old file stays, no NAME.tmp is left
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def open_nofollow(path: Path, flags: int, mode: int = 0o644) -> int:
    """``os.open`` of ``path`` that refuses a symbolic link with RunError naming it."""
    try:
        return os.open(path, flags | os.O_NOFOLLOW, mode)
    except OSError as err:
        if os.path.islink(path):
            refuse_link(path)
        raise


def save_figure(fig, path) -> None:
    """A matplotlib figure as PNG, replaced whole (never drawn through a link, nothing left
    half-written on a full disk)."""
    replace_whole(Path(path), lambda tmp: fig.savefig(tmp, dpi=120, format="png"))


def append_text(path: Path, text: str) -> None:
    """Appends ``text`` to ``path`` (made if missing; RunError when it is a link) and forces it to
    disk before returning; when that fails (a full disk) the file is cut back to what it was, so
    no part of ``text`` stays."""
    fd = open_nofollow(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT)
    try:
        size = os.fstat(fd).st_size
        data = memoryview(text.encode())
        try:
            while data:
                data = data[os.write(fd, data):]
            os.fsync(fd)
        except OSError:
            os.ftruncate(fd, size)
            raise
    finally:
        os.close(fd)


def write_text(path: Path, text: str) -> None:
    replace_whole(path, lambda tmp: tmp.write_text(text))


def write_json(path: Path, doc) -> None:
    """``doc`` as indented JSON with a final newline."""
    write_text(path, json.dumps(doc, indent=1) + "\n")


__all__ = ["DISK_FAULTS", "append_text", "open_nofollow", "refuse_link", "refuse_links_out", "replace_whole", "save_figure", "write_json", "write_text"]
