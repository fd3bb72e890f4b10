"""How a leaf's inputs are read, for both engines' leaf programs (``mjxskill.engine.mjx.leaves``
and ``mjxskill.engine.native.leaves``): each input is either a learnable parameter, read from
the parameter vector, or a fixed argument of the leaf (``mjxskill.ebt.primitives`` declares
which inputs each primitive has)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from mjxskill.errors import quote


class LeafInput(NamedTuple):
    """index: the input's position in the parameter vector (None: a fixed argument); value: the
    fixed argument's value (unused when ``index`` is set)."""

    index: int | None  # type: ignore[assignment]  # a field named like tuple.index, which it shadows
    value: float


def leaf_input(leaf, name: str, parameter_index: dict, default: float = 0.0) -> LeafInput:
    """Input ``name`` of ``leaf``; ``parameter_index`` maps learnable parameter names to their
    positions. Raises ValueError when the leaf names a parameter that is not learnable here."""
    if name in leaf.params:
        index = parameter_index.get(leaf.params[name])
        if index is None:
            raise ValueError(f"leaf {quote(leaf.name)}: input {quote(name)} names parameter {quote(leaf.params[name])}, "
                             "which is not learnable here")
        return LeafInput(index, math.nan)
    return LeafInput(None, float(leaf.args.get(name, default)))


def force_inputs(leaf, parameter_index: dict) -> tuple[np.ndarray, list[tuple[int, LeafInput]]]:
    """``apply_force``'s wrench (6,): its ``wrench`` argument (default none) and the force axes
    that ``force_x``/``force_y``/``force_z`` set, as (axis, input) pairs."""
    base = np.asarray(leaf.args.get("wrench", (0.0,) * 6), float)
    overrides = [(axis, leaf_input(leaf, f"force_{c}", parameter_index)) for axis, c in enumerate("xyz")
                 if f"force_{c}" in leaf.params or f"force_{c}" in leaf.args]
    return base, overrides


def spiral_inputs(leaf, parameter_index: dict) -> tuple[LeafInput, ...]:
    """``overlay_spiral``'s radius cap (m), path velocity (m/s) and pitch (m per turn)."""
    return tuple(leaf_input(leaf, name, parameter_index) for name in ("radius", "path_velocity", "pitch"))


def wait_ticks(leaf, tick_seconds: float) -> int:
    """BT ticks a ``wait`` leaf runs before it succeeds: its ``seconds`` rounded up to ticks."""
    return int(np.ceil(float(leaf.args["seconds"]) / tick_seconds - 1e-9))
