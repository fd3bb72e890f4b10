"""The optimizer's parameter prior of a run: from the scenario, or from an earlier run.

A run's prior (``RunConfig.prior``, stored in its ``config.yaml`` and so the same on every
resume) is a mapping ``{source, mean, std, weights}``: ``mjxskill.gp.Prior``'s fields in
parameter-vector order and where it came from. Two sources:

* the scenario's ``parameter_priors`` (the operator's belief, one ``{mean, std}`` per learnable
  parameter, ``mjxskill.scenario.skills.parameter_priors``): one component. A learnable parameter
  of the plan the scenario gives no prior for gets a flat one: its bounds' centre with a standard
  deviation of ``FLAT_STD_FACTOR`` times its range, whose density varies by less than 0.2 % over
  the bounds (a truncated Gaussian cannot be exactly uniform).
* ``train --prior-from RUN`` (transfer from an earlier run of a task with the same learnable
  parameters): one component per Pareto solution of that run, equal weights, each centred on the
  solution with a standard deviation of ``PRIOR_FROM_STD_FRACTION`` of the current range per
  parameter. It overrides the scenario's.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mjxskill.errors import RunError
from mjxskill.runs.run_dir import Run

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario.schema import Scenario
    from mjxskill.task import PlannedTask

FLAT_STD_FACTOR = 10.0
PRIOR_FROM_STD_FRACTION = 0.1
# At most this many components from an earlier run: its best Pareto solutions by their
# success objective (a front of hundreds would make every acquisition evaluation K times dearer).
MAX_COMPONENTS = 32


def scenario_prior(scn: Scenario, task: PlannedTask) -> dict | None:
    """The prior the scenario's ``parameter_priors`` give the plan's learnable parameters (None:
    the scenario gives none of them a prior)."""
    given = {name: scn.parameter_priors[name] for name in task.parameter_names if name in scn.parameter_priors}
    if not given:
        return None
    lo, hi = np.asarray(task.bounds, np.float64)
    mean = [float(given[n].mean if n in given else 0.5 * (a + b)) for n, a, b in zip(task.parameter_names, lo, hi)]
    std = [float(given[n].std if n in given else FLAT_STD_FACTOR * (b - a)) for n, a, b in zip(task.parameter_names, lo, hi)]
    return {"source": f"scenario {scn.source} (parameter_priors: {', '.join(given)})", "mean": [mean], "std": [std],
            "weights": [1.0]}


def prior_from_run(path: Path | str, parameter_names, bounds) -> dict:
    """The prior built from the Pareto solutions of the run in ``path``, for a task with
    ``parameter_names`` in ``bounds`` (2, P). RunError when that is no run with a front, or its
    learnable parameters are not these (naming what differs)."""
    run = Run(path)
    config = run.config()
    if config.repeats > 1:
        raise RunError(f"--prior-from {path} is a repeated run; name one of its runs, e.g. {run.sub_runs(config)[0].path}")
    names = tuple(parameter_names)
    if config.parameter_names != names:
        missing = [n for n in names if n not in config.parameter_names]
        extra = [n for n in config.parameter_names if n not in names]
        what = "; ".join(filter(None, (f"it lacks {', '.join(missing)}" if missing else "",
                                       f"it has {', '.join(extra)} besides" if extra else "",
                                       "" if missing or extra else "its parameters are in another order")))
        raise RunError(f"--prior-from {path}: its learnable parameters differ from this task's ({what}; "
                       f"this task: {', '.join(names)}; that run: {', '.join(config.parameter_names)})")
    front = run.front(config)
    order = np.argsort(-front.objectives[:, 0], kind="stable")[:MAX_COMPONENTS]
    lo, hi = np.asarray(bounds, np.float64)
    # A solution of a run with wider bounds may lie outside these: its component sits on the edge.
    mean = np.clip(front.params[order], lo, hi)
    std = np.broadcast_to(PRIOR_FROM_STD_FRACTION * (hi - lo), mean.shape)
    k = len(mean)
    return {"source": f"run {Path(path)} ({k} Pareto solution{'s' if k != 1 else ''}, std "
                      f"{PRIOR_FROM_STD_FRACTION:.0%} of each range)",
            "mean": mean.tolist(), "std": std.tolist(), "weights": [1.0 / k] * k}


def run_prior(scn: Scenario, task: PlannedTask, prior_from: Path | str | None = None) -> dict | None:
    """The prior of a new run of ``task``: the one of the run in ``prior_from`` (over the
    scenario's, and saying so) or, without it, the scenario's (None: none)."""
    own = scenario_prior(scn, task)
    if prior_from is None:
        return own
    prior = prior_from_run(prior_from, task.parameter_names, task.bounds)
    if own is not None:
        prior["source"] += "; overrides the scenario's parameter_priors"
    return prior


def describe_prior(prior: dict | None) -> str:
    """One line for the run's header."""
    if prior is None:
        return "prior: none (uniform warm-up, plain acquisition)"
    return f"prior: from the {prior['source']}, {len(prior['mean'])} component{'s' if len(prior['mean']) != 1 else ''}"


__all__ = ["FLAT_STD_FACTOR", "MAX_COMPONENTS", "PRIOR_FROM_STD_FRACTION", "describe_prior", "prior_from_run",
           "run_prior", "scenario_prior"]
