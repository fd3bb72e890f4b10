"""The optimizers that need an optional extra: what each imports, and what to install when it
is absent (``configure`` refuses such a run before its directory is made)."""

from __future__ import annotations

import importlib.util

# optimizer -> (the modules it imports, the extra that installs them)
NEEDS = {
    "optuna-nsga2": (("optuna",), "optuna"),
    "optuna-tpe": (("optuna",), "optuna"),
    "optuna-gp": (("optuna", "torch"), "optuna-gp"),
    "botorch-qlognehvi": (("botorch", "torch"), "botorch"),
}
NAMES = {"optuna": "Optuna", "torch": "PyTorch", "botorch": "BoTorch"}


def missing_extra(optimizer: str) -> str | None:
    """Why ``optimizer`` cannot run here (what is not installed and how to install it), or None
    (it can, or it needs no extra)."""
    modules, extra = NEEDS.get(optimizer, ((), ""))
    absent = [NAMES[m] for m in modules if importlib.util.find_spec(m) is None]
    if not absent:
        return None
    return (f"needs {' and '.join(absent)}, which {'is' if len(absent) == 1 else 'are'} not installed: "
            f"pip install 'mjxskill[{extra}]'")


__all__ = ["NEEDS", "missing_extra"]
