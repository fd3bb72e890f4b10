"""What a test that needs an OpenGL backend does without one: skip here, fail where rendering
must work (CI sets MJXSKILL_REQUIRE_RENDER=1 after installing Mesa's EGL: .ci/run)."""

import os

import pytest


def no_render(reason: str):
    """Skips the calling test (no OpenGL backend: ``reason``), or fails it under
    MJXSKILL_REQUIRE_RENDER."""
    if os.environ.get("MJXSKILL_REQUIRE_RENDER"):
        pytest.fail(f"rendering must work here (MJXSKILL_REQUIRE_RENDER): {reason}")
    pytest.skip(f"no OpenGL backend here: {reason}")
