"""Files replaced whole: a reader, or a run killed while it writes, sees the old file or the
new one, never part of one (the text goes to ``NAME.tmp`` beside it, then ``os.replace``).

A file that is a symbolic link is never written through: a link in a run directory to a file
elsewhere would have that file replaced (``refuse_link``: one RunError naming the link). Nor is
one read through when it leaves the directory: ``refuse_links_out`` walks a run or experiment
directory before a command reads it (an ``explore/`` folder, an evaluation file or a ``seed-<s>``
run linked elsewhere would be read, and written into, as the run's own); a link that stays
inside is harmless and allowed.

No name is looked up twice: a check of a path and a write to it by name would follow a folder
swapped for a link in between (a concurrent process, or a user's script). Every writer here
(``replace_whole``, ``append_text``, ``keep_copy``, ``remove_file``; the lock of
``mjxskill.runs.run_lock``) opens the file's folder once (``_held_folder``: reached from
``root``, the folder the command owns, without following a link, when the caller names it; the
nested files of ``evaluation/`` do) and takes every step below that descriptor (``dir_fd``,
``O_NOFOLLOW``), so the check is the open. A fault of the disk raised by any of them names the
file, not its temporary; a FIFO, folder or device in a file's place is refused, never waited on.

The one writer of a command's outputs (``mjxskill.runs.outputs.write_outputs``, built on this
module's folders and stagings; ``select``'s export, ``plan --export``, the explore page's cache
and export, the rendered frames): every output is checked before the first write: no folder between the root the command owns (a run, an export
folder the user named) and the output is a symbolic link (each is opened with the folder above
it held and ``O_NOFOLLOW``: ``open_folder``), the output itself is no link, and whatever is in
its place already holds the same content or, with ``replace`` (the command's ``--replace``),
is a file or folder of the same kind. Then each file or whole folder is staged beside its place
(``.<name>.<host>.<pid>.<hex>.creating``) and renamed into it, so a reader, or a writer killed
with SIGKILL, sees the old output or the new one, never part of one; a staging left by a killed
process is removed at the next creation beside it (``remove_stale_staging``). Nested files that
are appended or replaced one at a time (``evaluation/``, ``explore/`` of a run) are written
with the run as ``root``; ``make_folder`` makes their folder, refusing a link at any depth.
Files are read back (``read_below``) under the same rule, and only when they are regular
files (a FIFO would block the reader)."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import stat
from pathlib import Path
from typing import BinaryIO, Callable

from mjxskill._files import OPEN_FLAGS, NotRegularFile, not_regular, read_open
from mjxskill.errors import RunError, quote
from mjxskill.runs.folders import (  # noqa: F401  (re-exported: where they lived before runs.folders)
    DIR_FLAGS,
    STAGING,
    _this_host,
    check_folder,
    make_folder,
    open_folder,
    owning_root,
    read_below,
    remove_stale_staging,
    staging_name,
)


def refuse_link(path: Path) -> None:
    """Raises RunError naming ``path`` when it is a symbolic link."""
    if os.path.islink(path):
        raise _link_error(path, os.readlink(path))


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
                raise RunError(f"{path} is a symbolic link (to {quote(os.readlink(path), 200)}) that leaves {root}; mjxskill reads "
                               "and writes a run's files only in the run itself: replace the link by what it points "
                               "to, or remove it")


def _link_error(path: Path, target: str) -> RunError:
    return RunError(f"{path} is a symbolic link (to {quote(target, 200)}); mjxskill writes a run's files only in the run "
                    "itself: replace the link by the file it points to, or remove it")


def _held_folder(path: Path, root: Path | None) -> int:
    """A descriptor of ``path``'s folder, what every write below goes through (``dir_fd``): no
    name is looked up again once it is held, so a folder swapped for a link between a check and
    a write is never followed. The folder is reached from ``root`` without following a link
    (``open_folder``; RunError naming one); without ``root`` it is the root itself (the folder
    the caller named: a run, an experiment, unless this process holds the lock of a folder above
    it, ``folders.owning_root``: then from there)."""
    folder = Path(path).parent
    owner = owning_root(folder if root is None else root)
    if owner is not None:
        root, folder = owner, Path(os.path.abspath(folder))
    fd = open_folder(folder if root is None else Path(root), folder)
    if fd is None:
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), str(folder))
    return fd


def _located(err: OSError, path: Path) -> OSError:
    """``err`` naming ``path`` (an error of a call below a folder's descriptor names the bare
    file name or the temporary file, or nothing): what the command's fault line shows."""
    located = OSError(err.errno, err.strerror or str(err), str(path))
    return located if err.errno is not None else err


def _refuse_other(fd: int, path: Path) -> None:
    """RunError when ``path`` (in the folder ``fd``) is a link or no regular file; a missing one passes."""
    try:
        info = os.stat(path.name, dir_fd=fd, follow_symlinks=False)
    except FileNotFoundError:
        return
    if stat.S_ISLNK(info.st_mode):
        raise _link_error(path, os.readlink(path.name, dir_fd=fd))
    if not stat.S_ISREG(info.st_mode):
        raise RunError(f"{path} {not_regular(info.st_mode)}; mjxskill keeps its files there: remove "
                       "it, then run the command again")


NEW_FILE = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)


def replace_whole(path: Path, write: Callable[[BinaryIO], object], *, root: Path | None = None) -> None:
    """``write(fh)`` fills ``NAME.tmp`` beside ``path`` (``fh``: the binary file, opened new),
    which then replaces ``path``; every step below the folder's descriptor (``_held_folder``:
    from ``root``, the folder the command owns, when given). RunError when ``path`` is a
    symbolic link or no regular file, or a folder between ``root`` and it is a link. When writing
    fails (a full disk) ``path`` is unchanged, ``NAME.tmp`` removed and the OSError names ``path``."""
    path = Path(path)
    tmp = path.name + ".tmp"
    try:
        fd = _held_folder(path, root)
        try:
            _refuse_other(fd, path)
            with contextlib.suppress(FileNotFoundError):  # left by a killed writer, or a link: removed, never written through
                os.unlink(tmp, dir_fd=fd)
            file = os.open(tmp, NEW_FILE, 0o666, dir_fd=fd)
            try:
                with os.fdopen(file, "wb") as fh:
                    write(fh)
                os.replace(tmp, path.name, src_dir_fd=fd, dst_dir_fd=fd)
            except BaseException:  # a full disk, Ctrl-C: the old file stays, no NAME.tmp is left
                with contextlib.suppress(OSError):
                    os.unlink(tmp, dir_fd=fd)
                raise
        finally:
            os.close(fd)
    except OSError as err:
        raise _located(err, path) from None


def open_nofollow(path: Path, flags: int, mode: int = 0o644, *, dir_fd: int | None = None) -> int:
    """``os.open`` of ``path`` (its name in the folder ``dir_fd`` when given) that refuses a
    symbolic link with RunError naming it."""
    try:
        return os.open(path.name if dir_fd is not None else path, flags | os.O_NOFOLLOW, mode, dir_fd=dir_fd)
    except OSError as err:
        if err.errno == errno.ELOOP:
            with contextlib.suppress(OSError):
                raise _link_error(path, os.readlink(path.name if dir_fd is not None else path, dir_fd=dir_fd)) from None
        raise


def save_figure(fig, path, *, root: Path | None = None) -> None:
    """A matplotlib figure as PNG, replaced whole (never drawn through a link, nothing left
    half-written on a full disk)."""
    replace_whole(Path(path), lambda fh: fig.savefig(fh, dpi=120, format="png"), root=root)


def append_text(path: Path, text: str, *, root: Path | None = None) -> None:
    """Appends ``text`` to ``path`` (made if missing; RunError when it is a link or no regular
    file, or a folder between ``root`` and it is a link), opened below the folder's descriptor
    (``_held_folder``), and forces it to disk before returning; when that fails (a full disk) the
    file is cut back to what it was, so no part of ``text`` stays, and the OSError names ``path``."""
    path = Path(path)
    try:
        fd = _held_folder(path, root)
        try:  # O_NONBLOCK: a FIFO's open would wait for a reader
            file = open_nofollow(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0),
                                 0o666, dir_fd=fd)
        except OSError as err:
            if err.errno in (errno.ENXIO, errno.EISDIR):  # a FIFO without a reader, a folder
                _refuse_other(fd, path)
            raise
        finally:
            os.close(fd)
        try:
            info = os.fstat(file)
            if not stat.S_ISREG(info.st_mode):
                raise RunError(f"{path} {not_regular(info.st_mode)}; mjxskill keeps its files there: "
                               "remove it, then run the command again")
            os.set_blocking(file, True)
            data = memoryview(text.encode())
            try:
                while data:
                    data = data[os.write(file, data):]
                os.fsync(file)
            except OSError:
                os.ftruncate(file, info.st_size)
                raise
        finally:
            os.close(file)
    except OSError as err:
        raise _located(err, path) from None


def remove_file(path: Path, *, root: Path | None = None) -> None:
    """Removes the file ``path`` if it is there, below the folder's descriptor (``_held_folder``):
    a folder swapped for a link is never followed to remove a file elsewhere."""
    path = Path(path)
    try:
        fd = _held_folder(path, root)
    except FileNotFoundError:
        return
    try:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path.name, dir_fd=fd)
    finally:
        os.close(fd)


def keep_copy(path: Path, name: str) -> bool:
    """Keeps the regular file ``path`` as it is under ``name`` beside it (a hard link, or a copy
    where there are none), never over an existing file (False then); below the folder's
    descriptor, no link followed. A copy that cannot be finished (a full disk) is removed."""
    path = Path(path)
    try:
        fd = _held_folder(path, None)
        try:
            try:
                os.link(path.name, name, src_dir_fd=fd, dst_dir_fd=fd, follow_symlinks=False)
                return True
            except FileExistsError:
                return False
            except OSError:  # no hard links here: a copy, still never over an existing file
                pass
            try:
                source = os.open(path.name, OPEN_FLAGS | os.O_NOFOLLOW, dir_fd=fd)
            except OSError as err:
                if err.errno == errno.ELOOP:
                    raise _link_error(path, os.readlink(path.name, dir_fd=fd)) from None
                raise
            try:
                data = read_open(source, path)
            except NotRegularFile as err:
                raise RunError(f"{path} {err.strerror}; mjxskill reads only regular files") from None
            try:
                file = os.open(name, NEW_FILE, 0o666, dir_fd=fd)
            except FileExistsError:
                return False
            try:
                with os.fdopen(file, "wb") as fh:
                    fh.write(data)
                    fh.flush()
                    os.fsync(fh.fileno())
            except BaseException:
                with contextlib.suppress(OSError):
                    os.unlink(name, dir_fd=fd)
                raise
            return True
        finally:
            os.close(fd)
    except OSError as err:
        raise _located(err, path) from None


def write_text(path: Path, text: str, *, root: Path | None = None) -> None:
    replace_whole(path, lambda fh: fh.write(text.encode()), root=root)


def write_json(path: Path, doc, *, root: Path | None = None) -> None:
    """``doc`` as indented JSON with a final newline."""
    write_text(path, json.dumps(doc, indent=1) + "\n", root=root)


@contextlib.contextmanager
def created_whole(path: Path, what: str, on_failure=lambda: None):
    """Yields a new folder beside ``path`` to fill; renamed into place in one step when the block
    ends (onto nothing or an empty folder), removed when it fails or is interrupted, so ``path``
    appears whole or not at all. An OSError becomes a RunError naming ``what`` and ``path``
    (``on_failure()`` first, to say something better)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_staging(path.parent)
        # a fresh name beside it (mkdir is atomic), with the permissions mkdir gives
        staging = path.parent / staging_name(path.name)
        staging.mkdir()
    except OSError as err:
        if err.errno in DISK_FAULTS:  # a read-only file system: the machine's, not the input's (exit 1)
            raise OSError(err.errno, err.strerror, str(path)) from None
        raise RunError(f"cannot write the {what} {quote(str(path), 200)}: {err.strerror}") from None
    try:
        yield staging
        os.replace(staging, path)
    except OSError as err:
        shutil.rmtree(staging, ignore_errors=True)
        if err.errno in DISK_FAULTS:  # the machine's, not the input's: the command says so (exit 1), naming ``path``
            raise OSError(err.errno, err.strerror, str(path)) from None
        on_failure()
        raise RunError(f"cannot write the {what} {quote(str(path), 200)}: {err.strerror}") from None
    except BaseException:  # Ctrl-C half-way or a RunError inside: leave nothing behind
        shutil.rmtree(staging, ignore_errors=True)
        raise


__all__ = ["DIR_FLAGS", "DISK_FAULTS", "STAGING", "append_text", "check_folder", "created_whole", "keep_copy", "make_folder", "open_folder",
           "open_nofollow", "read_below", "refuse_link", "refuse_links_out", "remove_file", "remove_stale_staging", "replace_whole",
           "save_figure", "staging_name", "write_json", "write_text"]
