"""A scenario YAML with other physical values: the calibrated twin, or the "true" one a benchmark
records from. The source file's text is edited in place (its comments and layout kept): each
changed value's node is replaced, the ``scene`` and ``skill_library`` paths are made relative to
where the new file goes, and a ``calibrated`` section (``mjxskill.scenario.calibration``) says
what was fitted, with its intervals, and from what.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import yaml

from mjxskill.scenario.schema import Scenario


def _node(root: yaml.MappingNode, *keys: str) -> tuple[yaml.Node, yaml.Node] | None:
    """(key node, value node) of ``keys`` below ``root`` (None when absent)."""
    node: yaml.Node = root
    found = None
    for key in keys:
        if not isinstance(node, yaml.MappingNode):
            return None
        found = next(((k, v) for k, v in node.value if isinstance(k, yaml.ScalarNode) and k.value == key), None)
        if found is None:
            return None
        node = found[1]
    return found


def _number(value: float) -> str:
    return f"{value:.6g}"


def _flow(values) -> str:
    return "[" + ", ".join(_number(float(v)) for v in values) + "]"


def _flow_paths(paths: list[str]) -> str:
    """One path, or a flow list of them (``skill_library`` takes either)."""
    quoted = [yaml.safe_dump(p, default_style='"').strip() for p in paths]
    return quoted[0] if len(quoted) == 1 else "[" + ", ".join(quoted) + "]"


def _relative(target: str, folder: Path) -> str:
    try:
        return os.path.relpath(target, folder)
    except ValueError:  # another drive (Windows): no relative path
        return str(target)


def scenario_text(scn: Scenario, values: dict[str, float], out: Path, *, friction_range=False,
                  calibrated: str = "") -> str:
    """The text of ``scn``'s YAML with ``values`` ("<object>.<field>" -> value) in place of its
    own, to be written at ``out``: paths relative to it, ``friction_range`` ((low, high), None,
    or False to keep it) as the randomization's, ``calibrated`` (a YAML block) appended in
    place of any ``calibrated`` section the source had."""
    text = Path(scn.source).read_text(encoding="utf-8")
    root = yaml.compose(text)
    assert isinstance(root, yaml.MappingNode)
    edits: list[tuple[int, int, str]] = []  # (start, end, replacement) in the text

    def replace(keys, new: str) -> None:
        found = _node(root, *keys)
        if found is None:
            raise KeyError(".".join(keys))
        node = found[1]
        edits.append((node.start_mark.index, node.end_mark.index, new))

    offsets: dict[str, np.ndarray] = {}
    for key, value in values.items():
        name, _, field = key.partition(".")
        if field.startswith("com_offset."):
            offset = offsets.setdefault(name, np.array(scn.objects[name].com_offset, float))
            offset["xyz".index(field[-1])] = value
        else:
            replace(("objects", name, field), _number(value))
    for name, offset in offsets.items():
        if _node(root, "objects", name, "com_offset") is None:
            raise KeyError(f"objects.{name}.com_offset")
        replace(("objects", name, "com_offset"), _flow(offset))
    if friction_range is not False:
        replace(("randomization", "friction_range"), "null" if friction_range is None else _flow(friction_range))
    folder = out.resolve().parent
    replace(("scene",), _flow_paths([_relative(scn.scene, folder)]))
    if _node(root, "skill_library") is not None:
        replace(("skill_library",), _flow_paths([_relative(p, folder) for p in scn.libraries]))
    old = _node(root, "calibrated")
    if old is not None:  # a calibrated twin calibrated again: its old section goes
        edits.append((old[0].start_mark.index, old[1].end_mark.index, ""))
    for start, end, new in sorted(edits, reverse=True):
        text = text[:start] + new + text[end:]
    if calibrated:
        text = text.rstrip("\n") + "\n\n" + calibrated.rstrip("\n") + "\n"
    return text


__all__ = ["scenario_text"]
