"""Compiled behavior trees: an eBT as static arrays plus a pure, jittable, vmappable tick.

``compile_tree(tree)`` flattens an eBT (``mjxskill.ebt``) once on the host; ``init_state`` and
``tick`` are the optax-style pair that run it as a state machine under ``jit``/``vmap``/``scan``;
``init_rows`` and ``tick_rows`` run the same tick over many machines' numpy arrays (one compiled
loop over them, ``rows``).
"""

from mjxskill.bt_compiled.compile import CompiledTree, LeafSpec, compile_tree
from mjxskill.bt_compiled.tick import BTState, init_rows, init_state, started_leaves, tick, tick_rows, tick_sequence
from mjxskill.bt_compiled.trace import format_trace

__all__ = [
    "BTState",
    "CompiledTree",
    "LeafSpec",
    "compile_tree",
    "format_trace",
    "init_rows",
    "init_state",
    "started_leaves",
    "tick",
    "tick_rows",
    "tick_sequence",
]
