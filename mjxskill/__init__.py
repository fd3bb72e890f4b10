"""mjxskill: learn the free parameters of robot skills in MuJoCo MJX.

Data flow (one subpackage per stage): scenario YAML -> PDDL -> plan (``planner``) -> eBT
(``ebt``) -> compiled BT (``bt_compiled``) -> rollout -> objectives -> GP optimizer (``gp``).
"""

from mjxskill._runtime import configure_xla_flags as _configure_xla_flags

# Must run before anything creates a JAX backend (see mjxskill/_runtime.py).
_configure_xla_flags()

from mjxskill._runtime import enable_compilation_cache as _enable_compilation_cache  # noqa: E402

_enable_compilation_cache()

__version__ = "0.1.0"
__all__ = ["load_scenario", "compile_rollout", "__version__"]


def __getattr__(name):
    # Lazy so that `python -m mjxskill.plan` does not pay for importing MJX.
    if name == "load_scenario":
        from mjxskill.scenario import load_scenario

        return load_scenario
    if name == "compile_rollout":
        from mjxskill.rollout import compile_rollout

        return compile_rollout
    raise AttributeError(f"module 'mjxskill' has no attribute {name!r}")
