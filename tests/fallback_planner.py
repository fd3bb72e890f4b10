"""The planner the scenario tests use: ``mjxskill.planner.solve`` once it exists, until then
pyperplan's optimal A* (h_max) as a stand-in. Test-only; shipped code calls mjxskill.planner."""

import logging
import tempfile
from pathlib import Path


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
        raise RuntimeError("unsolvable")
    return [op.name for op in plan]


try:
    from mjxskill.planner import solve  # noqa: F401
except ImportError:
    solve = _pyperplan_solve
