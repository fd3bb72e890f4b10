"""The one writer of what a command writes (issue 47): ``select``'s export, ``plan --export``,
the explore page's cache and export, the rendered frames. ``write_outputs`` takes every output
(path -> a file's bytes, or a folder's files) at once:

* checked before the first write (``check_outputs``): no folder between the root the command
  owns (a run, the folder the user named) and the output is a link, each reached inside the one
  above it with ``O_NOFOLLOW`` (``mjxskill.runs.atomic_write.open_folder``); the output is no
  link and of the right kind; what is there holds the same content (harmless: left as it is) or,
  only with ``replace`` (the command's ``--replace``), other content;
* each file or whole folder staged beside its place (``.<name>.<host>.<pid>.<hex>.creating``)
  and renamed into it, so a reader, or a writer killed with SIGKILL, sees the old output or the
  new one, never part of one; the staging of a killed process is removed at the next write
  beside it (``remove_stale_staging``); a write that fails removes what it added;
* a fault of the disk raised as it is (the command's exit 1), any other OSError a RunError
  naming the path (exit 2).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Union

from mjxskill.errors import RunError, quote
from mjxskill.runs.atomic_write import DIR_FLAGS, DISK_FAULTS, open_folder, remove_stale_staging, staging_name

# What an output holds: a file's bytes, or a folder's files (name -> bytes)
Content = Union[bytes, Mapping[str, bytes]]


def _same_file(fd: int, name: str, info: os.stat_result, data: bytes) -> bool:
    if not stat.S_ISREG(info.st_mode) or info.st_size != len(data):
        return False
    file = os.open(name, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK, dir_fd=fd)
    with os.fdopen(file, "rb") as fh:
        return fh.read() == data


def _same_folder(fd: int, name: str, files: Mapping[str, bytes]) -> bool:
    inner = os.open(name, DIR_FLAGS, dir_fd=fd)
    try:
        if sorted(os.listdir(inner)) != sorted(files):
            return False
        return all(_same_file(inner, n, os.stat(n, dir_fd=inner, follow_symlinks=False), data) for n, data in files.items())
    finally:
        os.close(inner)


def in_the_way(root: Path, path: Path, content: Content) -> tuple[str, bool] | None:
    """Why ``content`` cannot take ``path``'s place without changing what is there: (a message
    naming it, whether ``replace`` may replace it), or None when nothing is there or it holds
    ``content`` already. A link, or a file where a folder goes (or the reverse), is never
    replaced; a folder above ``path`` that is a link is a RunError."""
    path = Path(path)
    fd = open_folder(root, path.parent)
    if fd is None:
        return None
    try:
        try:
            info = os.stat(path.name, dir_fd=fd, follow_symlinks=False)
        except FileNotFoundError:
            return None
        if stat.S_ISLNK(info.st_mode):
            return f"{path} is a symbolic link (to {quote(os.readlink(path.name, dir_fd=fd), 200)}), never written through", False
        folder = not isinstance(content, (bytes, bytearray))
        if folder != stat.S_ISDIR(info.st_mode) or not (folder or stat.S_ISREG(info.st_mode)):
            return f"{path} is {'no folder' if folder else 'no regular file'}", False
        if folder:
            same = _same_folder(fd, path.name, content)  # type: ignore[arg-type]
        else:
            same = _same_file(fd, path.name, info, bytes(content))  # type: ignore[arg-type]
        return None if same else (f"{path} holds {'other files' if folder else 'other content'}", True)
    finally:
        os.close(fd)


def check_outputs(root: Path, outputs: Mapping[Path, Content], *, replace: bool = False, hint: str = "",
                  flag: str = "") -> None:
    """RunError naming the first output of ``outputs`` (path -> content) that cannot be written
    (``in_the_way``; with ``replace``, other content may be replaced), with ``hint``: what the
    user can do about it, and ``flag``, the command's flag that replaces other content (named
    where it would help). Changes nothing. An OSError of the disk (``DISK_FAULTS``) is raised as
    it is; another one (a path too long, a loop of links) becomes a RunError naming the path."""
    for path, content in outputs.items():
        try:
            why = in_the_way(root, path, content)
        except OSError as err:
            if err.errno in DISK_FAULTS:
                raise
            raise RunError(f"cannot write {quote(str(path), 200)}: {err.strerror or err}") from None
        if why is not None and not (replace and why[1]):
            cure = ", ".join(filter(None, [hint, f"or replace it with {flag}" if why[1] and flag else ""]))
            raise RunError(f"{why[0]}; it is kept" + (f": {cure}" if cure else ""))


def _write_file(fd: int, name: str, data: bytes) -> None:
    file = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0), 0o644, dir_fd=fd)
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(file, view):]
        os.fsync(file)
    finally:
        os.close(file)


def _remove(fd: int, name: str) -> None:
    """Removes ``name`` (a file, or a folder and what it holds) in the folder ``fd``; no link is followed."""
    with contextlib.suppress(FileNotFoundError):
        if stat.S_ISDIR(os.stat(name, dir_fd=fd, follow_symlinks=False).st_mode):
            shutil.rmtree(name, dir_fd=fd)
        else:
            os.unlink(name, dir_fd=fd)


def _put(fd: int, name: str, content: Content) -> bool:
    """Stages ``content`` beside ``name`` in the folder ``fd`` and renames it into place (what held
    the same content already is left as it is); whether ``name`` is new."""
    try:
        info: os.stat_result | None = os.stat(name, dir_fd=fd, follow_symlinks=False)
    except FileNotFoundError:
        info = None
    folder = not isinstance(content, (bytes, bytearray))
    if info is not None and (_same_folder(fd, name, content) if folder else _same_file(fd, name, info, bytes(content))):  # type: ignore[arg-type]
        return False
    staging = staging_name(name)
    try:
        if folder:
            os.mkdir(staging, dir_fd=fd)
            inner = os.open(staging, DIR_FLAGS, dir_fd=fd)
            try:
                for file, data in content.items():  # type: ignore[union-attr]
                    if "/" in file or file in ("", ".", ".."):
                        raise ValueError(f"not a file name: {file!r}")
                    _write_file(inner, file, data)
            finally:
                os.close(inner)
        else:
            _write_file(fd, staging, bytes(content))  # type: ignore[arg-type]
        if info is None or not folder:
            os.replace(staging, name, src_dir_fd=fd, dst_dir_fd=fd)  # onto a file: in one step
        else:  # a folder onto a folder: the old one set aside, then removed
            old = staging_name(name, "replaced")
            os.rename(name, old, src_dir_fd=fd, dst_dir_fd=fd)
            try:
                os.rename(staging, name, src_dir_fd=fd, dst_dir_fd=fd)
            except BaseException:
                os.rename(old, name, src_dir_fd=fd, dst_dir_fd=fd)
                raise
            with contextlib.suppress(OSError):  # the new one is in place; a leftover is removed as a stale staging
                _remove(fd, old)
    except BaseException:
        with contextlib.suppress(OSError):
            _remove(fd, staging)
        raise
    return info is None


def write_outputs(root: Path, outputs: Mapping[Path, Content], *, replace: bool = False, hint: str = "",
                  flag: str = "") -> list[Path]:
    """Writes ``outputs`` (path below ``root`` -> a file's bytes or a folder's files): checked
    first (``check_outputs``, nothing written when one cannot be; ``hint``, ``flag``: its words),
    then each staged beside its
    place and renamed into it, the missing folders above it made (never through a link); an
    output already holding its content is left as it is. Returns the paths, in order. When a
    write fails, what this call added (outputs, folders) is removed again and what it replaced
    stays replaced, whole; an OSError of the disk (``DISK_FAULTS``) is raised as it is (the
    machine's fault), another one becomes a RunError naming the path."""
    root = Path(root)
    check_outputs(root, outputs, replace=replace, hint=hint, flag=flag)
    made: list[Path] = []
    added: list[Path] = []
    path = root
    try:
        for path, content in outputs.items():
            fd = open_folder(root, path.parent, create=True, made=made)
            assert fd is not None
            try:
                remove_stale_staging(path.parent, dir_fd=fd)
                if _put(fd, path.name, content):
                    added.append(path)
            finally:
                os.close(fd)
    except BaseException as err:
        for new in reversed(added):
            with contextlib.suppress(OSError, RunError):
                fd = open_folder(root, new.parent)
                if fd is not None:
                    try:
                        _remove(fd, new.name)
                    finally:
                        os.close(fd)
        for folder in reversed(made):
            with contextlib.suppress(OSError):
                os.rmdir(folder)
        if isinstance(err, OSError) and err.errno not in DISK_FAULTS:
            raise RunError(f"cannot write {quote(str(path), 200)}: {err.strerror or err}") from None
        if isinstance(err, OSError):  # the machine's fault, naming the output (not its staging)
            raise OSError(err.errno, err.strerror, str(path)) from None
        raise
    return list(outputs)


__all__ = ["Content", "check_outputs", "in_the_way", "write_outputs"]
