"""Shared test settings and fixtures.

tests/ mirrors the package: tests/<package>/ holds the tests of mjxskill/<package>/ (tests/engine/mjx/
those of mjxskill/engine/mjx/), and tests/ itself those of the top-level modules; tests/benchmarks/
holds those of the benchmark scripts, tests/project/ the checks of the repository as a whole (the
layout, the documentation, the package as installed, the committed experiments). Test modules are
imported by path (``--import-mode=importlib``, pyproject.toml), so two folders may hold test files
of the same name and no test module imports another; what tests share lives in tests/helpers/,
which this file puts on ``sys.path`` (``from cli_helpers import ...``), and in fixtures: here those
every folder may use, in a folder's conftest.py those of its tests.

mjxskill is imported first so that its XLA CPU flag and the persistent compilation cache are in
place before any test touches JAX. MuJoCo's GL backend is chosen before any test module imports
mujoco (it is fixed at that import: collected first, a module without rendering would otherwise
leave the renderer on GLFW, which has no display here). Expensive compiled functions are session
fixtures in the conftest.py or the test modules that need them (compiling MJX code costs seconds
to tens of seconds).
"""

import sys
from pathlib import Path

import pytest

HELPERS = Path(__file__).resolve().parent / "helpers"
# the helpers' asserts report their values as the tests' do (registered before any is imported)
pytest.register_assert_rewrite(*sorted(p.stem for p in HELPERS.glob("*.py")))
sys.path.insert(0, str(HELPERS))

import mjxskill  # noqa: F401, E402  (side effect: XLA flags and compilation cache)
from mjxskill.evaluation.render import default_gl  # noqa: E402

default_gl()  # MUJOCO_GL=egl when headless

import jax  # noqa: E402

jax.config.update("jax_enable_x64", False)


@pytest.fixture(scope="module")
def push():
    """The push scenario (loaded once per module; a module's own ``push`` fixture takes its place)."""
    from mjxskill.scenario import load_scenario  # lazy: a run of tests that load no scenario imports no mujoco here

    return load_scenario("push")


@pytest.fixture(scope="module")
def peg():
    """The peg scenario (loaded once per module; a module's own ``peg`` fixture takes its place)."""
    from mjxskill.scenario import load_scenario  # lazy: as push's

    return load_scenario("peg")
