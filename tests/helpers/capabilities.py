"""What a test does without an optional capability of the machine: skip here, but fail where the
capability must be there. CI sets MJXSKILL_REQUIRE_RENDER=1 after installing Mesa's EGL (MuJoCo's
offscreen rendering) and MJXSKILL_REQUIRE_EXTRAS=1 after installing the botorch extra (BoTorch
and PyTorch, which the test extra leaves out: a multi-GB download for most machines): .ci/run."""

import importlib
import os

import pytest


def missing(variable: str, why: str):
    """Skips the calling test (``why``), or fails it where ``variable`` says the capability must be there."""
    if os.environ.get(variable):
        pytest.fail(f"{why}, where it must be ({variable})")
    pytest.skip(why)


def no_render(reason: str):
    """Skips the calling test (no OpenGL backend: ``reason``), or fails it under MJXSKILL_REQUIRE_RENDER."""
    missing("MJXSKILL_REQUIRE_RENDER", f"no OpenGL backend here: {reason}")


def require(module: str):
    """``module`` imported, or the calling test skipped (failed under MJXSKILL_REQUIRE_EXTRAS)."""
    try:
        return importlib.import_module(module)
    except ImportError as err:
        missing("MJXSKILL_REQUIRE_EXTRAS", f"could not import {module!r}: {err}")
