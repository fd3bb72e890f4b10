"""The drawing backends, chosen before their libraries are imported: MuJoCo's OpenGL backend
(``default_gl``: ``MUJOCO_GL=egl`` without a display; mujoco reads it once, when imported) and
matplotlib's (``pyplot``: Agg, files only). Imports neither library at its top, so the
commands' --help and bad-input errors, which import the modules that draw, pay for neither.
"""

from __future__ import annotations

import os


def default_gl() -> None:
    """Picks the headless EGL backend unless the user chose one (call before importing mujoco)."""
    if "DISPLAY" not in os.environ:
        os.environ.setdefault("MUJOCO_GL", "egl")


def pyplot():
    """matplotlib.pyplot on the Agg backend (files only, no display needed)."""
    # lazy: pyplot costs ~0.4 s, and train's, select's and evaluate's --help and bad-input
    # errors import the modules that draw
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy, as matplotlib: and after the backend is chosen

    return plt


__all__ = ["default_gl", "pyplot"]
