"""Test-only: until mjxskill.planner exists, make it resolve to pyperplan for CLI subprocesses."""

import sys
import types

try:
    from mjxskill.planner import solve  # noqa: F401
except ImportError:
    for name in [m for m in sys.modules if m == "mjxskill.planner"]:
        del sys.modules[name]  # a half-imported namespace package
    sys.path.insert(0, __file__.rsplit("/", 2)[0])  # the tests folder
    import fallback_planner

    shim = types.ModuleType("mjxskill.planner")
    shim.solve = fallback_planner._pyperplan_solve
    shim.Unsolvable = fallback_planner.Unsolvable
    sys.modules["mjxskill.planner"] = shim
    import mjxskill

    mjxskill.planner = shim  # the failed import left the namespace package as an attribute
