"""Tests of what needs an optional extra that the test extra leaves out (BoTorch and PyTorch: a
multi-GB download for most machines): skipped without it, but where it must be there (CI sets
MJXSKILL_REQUIRE_EXTRAS=1 after installing the botorch extra: .ci/run) a missing one fails."""

import os

import pytest


def require(module: str):
    """``module`` imported, or the calling test skipped (failed under MJXSKILL_REQUIRE_EXTRAS)."""
    if os.environ.get("MJXSKILL_REQUIRE_EXTRAS"):
        import importlib

        try:
            return importlib.import_module(module)
        except ImportError as err:
            pytest.fail(f"{module} must be installed here (MJXSKILL_REQUIRE_EXTRAS): {err}")
    return pytest.importorskip(module)
