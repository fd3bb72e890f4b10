"""Files replaced whole: a reader, or a run killed while it writes, sees the old file or the
new one, never part of one (the text goes to ``NAME.tmp`` beside it, then ``os.replace``).

A file that is a symbolic link is never written through: a link in a run directory to a file
elsewhere would have that file replaced (``refuse_link``: one RunError naming the link). Nor is
one read through when it leaves the directory: ``refuse_links_out`` walks a run or experiment
directory before a command reads it (an ``explore/`` folder, an evaluation file or a ``seed-<s>``
run linked elsewhere would be read, and written into, as the run's own); a link that stays
inside is harmless and allowed.

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
are appended or replaced one at a time (``evaluation/``, ``explore/`` of a run) reach their
folder through ``make_folder``, which refuses a link at any depth below the root.
Files are read back (``read_below``) under the same rule, and only when they are regular
files (a FIFO would block the reader)."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import secrets
import shutil
import socket
from pathlib import Path
from typing import Callable

from mjxskill._files import OPEN_FLAGS, NotRegularFile, read_open
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


def replace_whole(path: Path, write: Callable[[Path], object], *, root: Path | None = None) -> None:
    """``write(tmp)`` fills ``NAME.tmp`` beside ``path``, which then replaces ``path``; RunError
    when ``path`` is a symbolic link, or (``root`` given) a folder between ``root`` and it is one.
    When writing fails (a full disk) ``path`` is unchanged and ``NAME.tmp`` removed."""
    if root is not None:
        check_folder(root, Path(path).parent)
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
    except OSError:
        if os.path.islink(path):
            refuse_link(path)
        raise


def save_figure(fig, path) -> None:
    """A matplotlib figure as PNG, replaced whole (never drawn through a link, nothing left
    half-written on a full disk)."""
    replace_whole(Path(path), lambda tmp: fig.savefig(tmp, dpi=120, format="png"))


def append_text(path: Path, text: str, *, root: Path | None = None) -> None:
    """Appends ``text`` to ``path`` (made if missing; RunError when it is a link, or a folder
    between ``root`` and it) and forces it to disk before returning; when that fails (a full
    disk) the file is cut back to what it was, so no part of ``text`` stays."""
    if root is not None:
        check_folder(root, Path(path).parent)
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


def write_text(path: Path, text: str, *, root: Path | None = None) -> None:
    replace_whole(path, lambda tmp: tmp.write_text(text), root=root)


def write_json(path: Path, doc, *, root: Path | None = None) -> None:
    """``doc`` as indented JSON with a final newline."""
    write_text(path, json.dumps(doc, indent=1) + "\n", root=root)




# -- staging: a file or folder made beside its place, renamed into it -----------------------------
# .<name>.<host>.<pid>.<hex>.creating (a new output) or .replaced (the output it took the place
# of, removed right after); stagings of before the host was named lack <host>.
STAGING = re.compile(r"\.(?P<name>.+?)(?:\.(?P<host>[A-Za-z0-9-]+))?\.(?P<pid>\d+)\.[0-9a-f]{8}\.(?:creating|replaced)")


def _this_host() -> str:
    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname()) or "host"


def staging_name(name: str, kind: str = "creating") -> str:
    """A fresh name beside ``name`` for a staging (``kind``: creating or replaced)."""
    return f".{name}.{_this_host()}.{os.getpid()}.{secrets.token_hex(4)}.{kind}"


def _process_gone(pid: int) -> bool:
    """Whether no process ``pid`` runs on this host (one of another user's still runs)."""
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):  # none, or a number larger than any pid
        return True
    except PermissionError:
        return False
    return False


def remove_stale_staging(parent: Path) -> list[Path]:
    """Removes the stagings (folders and files) in ``parent`` of processes of this host that no
    longer run (killed while creating a run, an experiment or an output); returns them. One of
    another host, of a running process or that is a link is left alone."""
    removed: list[Path] = []
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return removed
    for entry in entries:
        match = STAGING.fullmatch(entry.name)
        if match is None or entry.is_symlink() or not (entry.is_dir(follow_symlinks=False) or entry.is_file(follow_symlinks=False)):
            continue
        if match["host"] not in (None, _this_host()) or not _process_gone(int(match["pid"])):
            continue
        if entry.name.endswith(".replaced") and not os.path.lexists(os.path.join(parent, match["name"])):
            # killed between setting the old output aside and renaming the new one in: the old one goes back
            with contextlib.suppress(OSError):
                os.rename(entry.path, os.path.join(parent, match["name"]))
            continue
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(entry.path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                os.unlink(entry.path)
        removed.append(Path(entry.path))
    return removed


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
        raise RunError(f"cannot write the {what} {str(path)!r}: {err.strerror}") from None
    try:
        yield staging
        os.replace(staging, path)
    except OSError as err:
        shutil.rmtree(staging, ignore_errors=True)
        if err.errno in DISK_FAULTS:  # the machine's, not the input's: the command says so (exit 1)
            raise
        on_failure()
        raise RunError(f"cannot write the {what} {str(path)!r}: {err.strerror}") from None
    except BaseException:  # Ctrl-C half-way or a RunError inside: leave nothing behind
        shutil.rmtree(staging, ignore_errors=True)
        raise


# -- folders below a root, reached without following a link ---------------------------------------
DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)


def _parts(root: Path, path: Path) -> tuple[str, ...]:
    """The names leading from ``root`` to ``path``; RunError when ``path`` is not below it."""
    try:
        parts = Path(path).relative_to(root).parts
    except ValueError:
        raise RunError(f"{path} is not inside {root}") from None
    if ".." in parts:
        raise RunError(f"{path} leaves {root} (a '..' in it)")
    return parts


def _not_a_folder(path: Path) -> RunError:
    if os.path.islink(path):
        return RunError(f"{path} is a symbolic link (to {os.readlink(path)!r}); mjxskill never writes or reads through "
                        "a link below the folder it was given: replace the link by the folder it points to, or remove it")
    return RunError(f"{path} is in the way: a folder goes there and it is no folder; move it away")


def open_folder(root: Path, folder: Path, *, create: bool = False, made: list[Path] | None = None) -> int | None:
    """A file descriptor of ``folder`` (``root`` or a folder below it), each folder below ``root``
    opened inside the one above it without following a link (``root`` itself, which the user
    named, may be one). A missing folder is made when ``create`` (and appended to ``made``), else
    the answer is None. RunError naming the first that is a link or no folder; the caller closes
    the descriptor."""
    root = Path(root)
    parts = _parts(root, folder)
    if create and not os.path.isdir(root):
        missing = []  # root and the folders above it that are not there yet, deepest first
        for above in (root, *root.parents):
            if os.path.lexists(above):
                break
            missing.append(above)
        try:
            root.mkdir(parents=True)
        except FileExistsError:
            pass
        else:
            if made is not None:  # every folder made, so that a failed write can remove them all
                made.extend(reversed(missing))
    try:
        fd = os.open(root, os.O_RDONLY | os.O_DIRECTORY | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        if create:
            raise
        return None
    except NotADirectoryError:
        raise _not_a_folder(root) from None
    here = root
    try:
        for name in parts:
            here = here / name
            try:
                inner = os.open(name, DIR_FLAGS, dir_fd=fd)
            except FileNotFoundError:
                if not create:
                    os.close(fd)
                    return None
                try:
                    os.mkdir(name, dir_fd=fd)
                    if made is not None:
                        made.append(here)
                except FileExistsError:
                    pass
                try:
                    inner = os.open(name, DIR_FLAGS, dir_fd=fd)
                except OSError as err:
                    if err.errno in (errno.ELOOP, errno.ENOTDIR):
                        raise _not_a_folder(here) from None
                    raise
            except OSError as err:
                if err.errno in (errno.ELOOP, errno.ENOTDIR):
                    raise _not_a_folder(here) from None
                raise
            os.close(fd)
            fd = inner
    except BaseException:
        with contextlib.suppress(OSError):
            os.close(fd)
        raise
    return fd


def check_folder(root: Path, folder: Path) -> None:
    """RunError when a folder between ``root`` and ``folder`` (included) is a link or no folder."""
    fd = open_folder(root, folder)
    if fd is not None:
        os.close(fd)


def make_folder(root: Path, folder: Path) -> Path:
    """``folder`` (below ``root``), made where missing, never through a link (RunError naming
    it); returns ``folder``."""
    os.close(open_folder(root, folder, create=True))  # type: ignore[arg-type]  # create: never None
    return folder


def read_below(root: Path, path: Path, limit: int | None = None) -> bytes:
    """The bytes of the regular file ``path`` below ``root``, reached without following a link;
    RunError naming it when it, or a folder above it, is a link, or it is no regular file (a
    FIFO would block), or it is larger than ``limit``."""
    path = Path(path)
    fd = open_folder(root, path.parent)
    if fd is None:
        raise RunError(f"{path} is missing")
    try:
        try:
            file = os.open(path.name, OPEN_FLAGS | os.O_NOFOLLOW, dir_fd=fd)
        except FileNotFoundError:
            raise RunError(f"{path} is missing") from None
        except OSError as err:
            if err.errno == errno.ELOOP:
                raise _not_a_folder(path) from None
            raise
    finally:
        os.close(fd)
    try:
        data = read_open(file, path, limit)
    except NotRegularFile as err:
        raise RunError(f"{path} {err.strerror}; mjxskill reads only regular files") from None
    if limit is not None and len(data) > limit:
        raise RunError(f"{path} holds more than the {limit} bytes expected")
    return data


__all__ = ["DIR_FLAGS", "DISK_FAULTS", "STAGING", "append_text", "check_folder", "created_whole", "make_folder", "open_folder",
           "open_nofollow", "read_below", "refuse_link", "refuse_links_out", "remove_stale_staging", "replace_whole",
           "save_figure", "staging_name", "write_json", "write_text"]
