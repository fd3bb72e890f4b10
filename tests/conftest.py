"""Shared test settings.

mjxskill is imported first so that its XLA CPU flag and the persistent compilation cache are in
place before any test touches JAX. MuJoCo's GL backend is chosen before any test module imports
mujoco (it is fixed at that import: collected first, a module without rendering would otherwise
leave the renderer on GLFW, which has no display here). Expensive compiled functions are session
fixtures in the test modules that need them (compiling MJX code costs seconds to tens of
seconds).
"""

import mjxskill  # noqa: F401  (side effect: XLA flags and compilation cache)
from mjxskill.evaluation.render import default_gl

default_gl()  # MUJOCO_GL=egl when headless

import jax

jax.config.update("jax_enable_x64", False)


import pytest  # noqa: E402


@pytest.fixture(scope="session")
def push_rollout():
    """The push task compiled once for the session: 2 worlds per parameter set, 8 s episodes
    (the push ends in the goal corner after about 7 s). Callers keep 2 parameter sets per call
    so that every call reuses the one compiled program."""
    from mjxskill import compile_rollout, load_scenario

    scn = load_scenario("push")
    return scn, compile_rollout(scn, worlds=2, episode_seconds=8.0)
