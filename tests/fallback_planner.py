"""Planners for the scenario tests (test-only; shipped code calls mjxskill.planner.solve).

``solve``: ``mjxskill.planner.solve`` once it exists, until then pyperplan's optimal A* (h_max)
as a stand-in. ``fast_downward_plan``: Fast Downward (seq-opt-lmcut) from the up-fast-downward
wheel, the independent oracle for exported PDDL. ``SHIM_DIR``: a folder to put on PYTHONPATH of
a subprocess so that ``mjxskill.planner`` resolves to the stand-in when the real one is missing.
"""

import importlib.util
import logging
import subprocess
import sys
import tempfile
from pathlib import Path


class Unsolvable(Exception):
    pass


def _pyperplan_solve(domain: str, problem: str) -> list[str]:
    from pyperplan import planner
    from pyperplan.heuristics.relaxation import hMaxHeuristic
    from pyperplan.search import astar_search

    logging.disable(logging.INFO)
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "domain.pddl").write_text(domain)
        (Path(tmp) / "problem.pddl").write_text(problem)
        task = planner._ground(planner._parse(str(Path(tmp) / "domain.pddl"), str(Path(tmp) / "problem.pddl")))
    plan = planner._search(task, astar_search, hMaxHeuristic(task))
    if plan is None:
        raise Unsolvable("pyperplan found no plan")
    return [op.name for op in plan]


try:
    from mjxskill.planner import solve  # noqa: F401

    HAVE_PLANNER = True
except ImportError:
    solve = _pyperplan_solve
    HAVE_PLANNER = False


def fast_downward_plan(domain: str, problem: str) -> list[str] | None:
    """Fast Downward's optimal plan as "(action arg ...)" strings, None if it proves none."""
    package = Path(importlib.util.find_spec("up_fast_downward").submodule_search_locations[0])
    driver = package / "downward" / "fast-downward.py"
    with tempfile.TemporaryDirectory() as tmp:
        Path(tmp, "domain.pddl").write_text(domain)
        Path(tmp, "problem.pddl").write_text(problem)
        run = subprocess.run(
            [sys.executable, str(driver), "--alias", "seq-opt-lmcut", "domain.pddl", "problem.pddl"],
            cwd=tmp, capture_output=True, text=True, timeout=120,
        )
        plan_file = Path(tmp, "sas_plan")
        if not plan_file.exists():
            if "unsolvable" in run.stdout.lower() or run.returncode == 12:
                return None
            raise AssertionError(f"Fast Downward failed (exit {run.returncode}):\n{run.stdout[-2000:]}\n{run.stderr[-2000:]}")
        return [line.strip() for line in plan_file.read_text().splitlines() if not line.startswith(";")]


SHIM_DIR = Path(__file__).parent / "planner_shim"
