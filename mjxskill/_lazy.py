"""Names a package loads on first use (PEP 562), so that importing the package imports none of
its heavy modules: ``mjxskill`` (MJX), ``mjxskill.engine.mjx`` (MJX) and ``mjxskill.gp`` (jax)."""

from __future__ import annotations

import importlib
from typing import Any, Callable


def lazy_getattr(package: str, exports: dict[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``package``: ``name`` is imported from the module
    ``exports[name]`` when first asked for; any other name is an AttributeError."""

    def __getattr__(name: str) -> Any:
        if name in exports:
            return getattr(importlib.import_module(exports[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__


__all__ = ["lazy_getattr"]
