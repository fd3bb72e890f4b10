"""Rollouts: the compiled BT driving the impedance controller in domain-randomized MJX worlds,
rewards grouped into objectives. ``compile_rollout`` is the entry point.

Engine-independent modules (``types``, ``bindings``, ``worlds``) import no MJX and are shared with
the native engine (``mjxskill.engine.native``); the compiled engine is ``episode``, ``leaves``,
``rewards``, ``compiled``, ``program_cache`` and ``sharding``. The names below load lazily, so
importing a shared module does not import MJX.
"""

import importlib

_EXPORTS = {
    "MJXRollout": "mjxskill.engine.mjx.compiled",
    "compile_rollout": "mjxskill.engine.mjx.compiled",
    "RolloutOutput": "mjxskill.engine.common.types",
    "Worlds": "mjxskill.engine.common.worlds",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'mjxskill.engine.mjx' has no attribute {name!r}")
