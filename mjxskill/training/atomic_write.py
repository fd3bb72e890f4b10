"""Files replaced whole: a reader, or a run killed while it writes, sees the old file or the
new one, never part of one (the text goes to ``NAME.tmp`` beside it, then ``os.replace``)."""

from __future__ import annotations

import json
import os
from pathlib import Path


def write_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_json(path: Path, doc) -> None:
    """``doc`` as indented JSON with a final newline."""
    write_text(path, json.dumps(doc, indent=1) + "\n")


__all__ = ["write_json", "write_text"]
