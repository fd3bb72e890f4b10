"""The compiled engine: the BT compiled into a state machine driving the impedance controller in
domain-randomized MJX worlds, every parameter set in every world in one jitted call.
``compile_rollout`` is the entry point.

Modules: ``compiled`` (``MJXRollout``, ``compile_rollout``), ``episode`` (one world's episode as
nested scans), ``batching`` (over a leading world axis), ``leaves`` (each primitive's effect),
``controller`` and ``motion`` (the impedance law and motion generator in JAX),
``program_cache`` (the compiled program on disk) and ``sharding`` (over local devices). What it
shares with the native engine is in ``mjxskill.engine.common``. The names below load lazily,
so importing this package does not import MJX.
"""

from mjxskill._lazy import lazy_getattr

_EXPORTS = {
    "MJXRollout": "mjxskill.engine.mjx.compiled",
    "compile_rollout": "mjxskill.engine.mjx.compiled",
    "RolloutOutput": "mjxskill.engine.common.types",
    "Worlds": "mjxskill.engine.common.worlds",
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_getattr(__name__, _EXPORTS)
