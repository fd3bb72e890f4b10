"""Fast Downward (seq-opt-lmcut) from the up-fast-downward wheel: an independent planner that
checks the PDDL we export. Test-only; the driver runs as a script, the package is not imported
(it needs unified_planning)."""

import importlib.util
import subprocess
import sys
import tempfile
from pathlib import Path


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
