"""Files replaced whole: a reader, or a run killed while it writes, sees the old file or the
new one, never part of one (the text goes to ``NAME.tmp`` beside it, then ``os.replace``).

A file that is a symbolic link is never written through: a link in a run directory to a file
elsewhere would have that file replaced (``refuse_link``: one RunError naming the link)."""

from __future__ import annotations

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


def replace_whole(path: Path, write: Callable[[Path], None]) -> None:
    """``write(tmp)`` fills ``NAME.tmp`` beside ``path``, which then replaces ``path``; RunError
    when ``path`` is a symbolic link."""
    refuse_link(path)
    tmp = path.with_name(path.name + ".tmp")
    if os.path.lexists(tmp):  # left by a killed writer, or a link: removed, never written through
        os.unlink(tmp)
    write(tmp)
    os.replace(tmp, path)


def open_nofollow(path: Path, flags: int, mode: int = 0o644) -> int:
    """``os.open`` of ``path`` that refuses a symbolic link with RunError naming it."""
    try:
        return os.open(path, flags | os.O_NOFOLLOW, mode)
    except OSError as err:
        if os.path.islink(path):
            refuse_link(path)
        raise


def write_text(path: Path, text: str) -> None:
    replace_whole(path, lambda tmp: tmp.write_text(text))


def write_json(path: Path, doc) -> None:
    """``doc`` as indented JSON with a final newline."""
    write_text(path, json.dumps(doc, indent=1) + "\n")


__all__ = ["open_nofollow", "refuse_link", "replace_whole", "write_json", "write_text"]
