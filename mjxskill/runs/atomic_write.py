"""Files replaced whole: a reader, or a run killed while it writes, sees the old file or the
new one, never part of one (the text goes to ``NAME.tmp`` beside it, then ``os.replace``)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Callable


def replace_whole(path: Path, write: Callable[[Path], None]) -> None:
    """``write(tmp)`` fills ``NAME.tmp`` beside ``path``, which then replaces ``path``."""
    tmp = path.with_name(path.name + ".tmp")
    write(tmp)
    os.replace(tmp, path)


def write_text(path: Path, text: str) -> None:
    replace_whole(path, lambda tmp: tmp.write_text(text))


def write_json(path: Path, doc) -> None:
    """``doc`` as indented JSON with a final newline."""
    write_text(path, json.dumps(doc, indent=1) + "\n")


__all__ = ["replace_whole", "write_json", "write_text"]
