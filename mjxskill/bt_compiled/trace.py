"""Tick-by-tick traces of a compiled tree as text tables (py_trees-style), for tests and logs."""

from __future__ import annotations

import numpy as np

from mjxskill.bt_compiled.compile import CompiledTree
from mjxskill.ebt.nodes import SYMBOLS, Kind

# One letter per status value; "-" marks a node that was not ticked (-1).
STATUS_LETTERS = {-1: "-", 0: "R", 1: "S", 2: "F"}


def format_trace(ct: CompiledTree, node_status, symbols: bool = False) -> str:
    """Table with one row per node (pre-order, indented by depth) and one column per tick.

    Args:
        ct: the compiled tree.
        node_status: (T, n) int, e.g. ``tick_sequence``'s node statuses (-1: not ticked).
        symbols: prefix each name with its processor symbol (``->*``, ``||FS``, ...).

    Returns:
        Lines like ``"  ToStart    R R S - -"``; names are left-aligned in one column.
    """
    table = np.asarray(node_status)
    if table.ndim != 2 or table.shape[1] != ct.num_nodes:
        raise ValueError(f"node_status must have shape (T, {ct.num_nodes}), got {table.shape}")
    depth = np.zeros(ct.num_nodes, int)
    for nid in range(1, ct.num_nodes):  # parents precede children in pre-order
        depth[nid] = depth[ct.parent[nid]] + 1
    labels = []
    for nid in range(ct.num_nodes):
        kind = Kind(int(ct.kind[nid]))
        label = ct.names[nid]
        if symbols:
            count = f"{ct.count[nid]}" if kind in (Kind.REPEAT, Kind.RETRY, Kind.TIMEOUT) else ""
            label = f"{SYMBOLS[kind]}{count} {label}"
        labels.append("  " * depth[nid] + label)
    width = max(len(label) for label in labels)
    lines = []
    for nid, label in enumerate(labels):
        letters = " ".join(STATUS_LETTERS.get(int(s), "?") for s in table[:, nid])
        lines.append(f"{label.ljust(width)}  {letters}".rstrip())
    return "\n".join(lines)
