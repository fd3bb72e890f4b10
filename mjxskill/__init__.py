"""mjxskill: learn the free parameters of robot skills in MuJoCo MJX.

Data flow, one package per stage (``docs/architecture.md``): scenario YAML (``scenario``) ->
PDDL, plan (``planner``) -> eBT (``ebt``), joined in ``task.plan_task`` -> compiled BT
(``bt_compiled``) -> rollout over MJX (``rollout``, with ``sim``; ``native`` is the native
MuJoCo engine) -> objectives -> GP optimizer (``gp``) -> next batch, driven by ``training`` and
the command line (``cli``).

    from mjxskill import load_scenario, plan_task, build_model, compile_rollout
"""

from mjxskill._lazy import lazy_getattr
from mjxskill._runtime import configure_xla_flags as _configure_xla_flags

# Must run before anything creates a JAX backend (see mjxskill/_runtime.py). Importing the
# package creates no directory: the compile caches are switched on by compile_rollout and the
# commands (mjxskill._runtime.enable_compilation_cache).
_configure_xla_flags()

__version__ = "0.1.0"

# Lazy, so that `python -m mjxskill.plan` does not pay for importing MJX.
_EXPORTS = {
    "load_scenario": "mjxskill.scenario",
    "plan_task": "mjxskill.task",
    "build_model": "mjxskill.sim.model",
    "compile_rollout": "mjxskill.engine.mjx.compiled",
}

__all__ = ["__version__", *_EXPORTS]
__getattr__ = lazy_getattr(__name__, _EXPORTS)
