"""Folders below a root the command owns, reached without following a link, and the stagings
made beside a place (``mjxskill.runs.atomic_write``, which re-exports every name here, and
``mjxskill.runs.outputs`` write through them).

``open_folder`` opens each folder from the root down inside the one above it, with
``O_NOFOLLOW``: a folder that is a link is one RunError naming it, never followed; the
descriptor it returns is what a writer holds from its check to its write. A staging
(``.<name>.<host>.<pid>.<hex>.creating``, or ``.replaced`` for the output it took the place of)
left by a process killed on this host is removed at the next write beside it
(``remove_stale_staging``)."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import shutil
import socket
from pathlib import Path

from mjxskill._files import OPEN_FLAGS, NotRegularFile, read_open
from mjxskill.errors import RunError, quote


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


def remove_stale_staging(parent: Path, *, dir_fd: int | None = None) -> list[Path]:
    """Removes the stagings (folders and files) in ``parent`` of processes of this host that no
    longer run (killed while creating a run, an experiment or an output); returns them. One of
    another host, of a running process or that is a link is left alone. With ``dir_fd`` (a
    descriptor of ``parent``, held by the writer) every step is taken in it, so a ``parent``
    swapped for a link is never followed."""
    removed: list[Path] = []
    try:
        entries = list(os.scandir(parent if dir_fd is None else dir_fd))
    except OSError:
        return removed
    # each name in the folder held (dir_fd) or below the path
    at = (lambda name: name) if dir_fd is not None else (lambda name: os.path.join(parent, name))
    for entry in entries:
        match = STAGING.fullmatch(entry.name)
        if match is None or entry.is_symlink() or not (entry.is_dir(follow_symlinks=False) or entry.is_file(follow_symlinks=False)):
            continue
        if match["host"] not in (None, _this_host()) or not _process_gone(int(match["pid"])):
            continue
        if entry.name.endswith(".replaced") and not _lexists(at(match["name"]), dir_fd):
            # killed between setting the old output aside and renaming the new one in: the old one goes back
            with contextlib.suppress(OSError):
                os.rename(at(entry.name), at(match["name"]), src_dir_fd=dir_fd, dst_dir_fd=dir_fd)
            continue
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(at(entry.name), ignore_errors=True, dir_fd=dir_fd)
        else:
            with contextlib.suppress(OSError):
                os.unlink(at(entry.name), dir_fd=dir_fd)
        removed.append(Path(parent, entry.name))
    return removed


def _lexists(name: str, dir_fd: int | None) -> bool:
    try:
        os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
    except FileNotFoundError:
        return False
    return True


# -- folders below a root, reached without following a link ---------------------------------------
DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)


# The folders whose writer's lock this process holds (``runs.run_lock``): a run, an experiment.
# A write given no root is reached from the outermost of them that holds it, so a folder inside
# an experiment (``optimizer/seed-3``) swapped for a link while the experiment runs is refused,
# not written through.
_OWNED: list[Path] = []


def own_folder(folder: Path) -> Path:
    """Marks ``folder`` as owned while its lock is held; returns the entry ``disown_folder`` takes."""
    entry = Path(os.path.abspath(folder))
    _OWNED.append(entry)
    return entry


def disown_folder(entry: Path) -> None:
    with contextlib.suppress(ValueError):
        _OWNED.remove(entry)


def owning_root(folder: Path) -> Path | None:
    """The outermost owned folder (``own_folder``) that is ``folder`` or holds it; None: none."""
    here = Path(os.path.abspath(folder))
    holders = [root for root in _OWNED if root == here or root in here.parents]
    return min(holders, key=lambda root: len(root.parts)) if holders else None


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
        return RunError(f"{path} is a symbolic link (to {quote(os.readlink(path), 200)}); mjxskill never writes or reads through "
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


__all__ = ["DIR_FLAGS", "STAGING", "check_folder", "disown_folder", "make_folder", "open_folder", "own_folder", "owning_root",
           "read_below", "remove_stale_staging",
           "staging_name"]
