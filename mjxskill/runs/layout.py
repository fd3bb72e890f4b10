"""Which runs a directory holds, and of which kind: the one place that knows the three layouts.

A **run** (``train``; ``mjxskill.runs.run_dir``)::

    RUN/config.yaml, evaluations.csv, pareto.csv, ...     one optimizer or random-search run
    RUN/evaluation/                                      after ``evaluate RUN``

A **repeated run** (``train --repeats R``): ``config.yaml`` with ``repeats: R`` and no
evaluations of its own, one run per seed::

    REP/config.yaml, repeats.yaml, pareto_runs.png
    REP/seed-<s>/  for s = seed .. seed+R-1              each a run as above
    REP/evaluation/                                      after ``evaluate REP`` (pooled)

An **experiment** (``python -m mjxskill.experiment``; ``mjxskill.experiment``)::

    EXP/experiment.yaml                                  the evaluation protocol
    EXP/domain.pddl, problem.pddl, plan.txt, bt.txt      the planned task, once (its runs hold none)
    EXP/optimizer/                                       a repeated run, optimizer mobo
    EXP/random_search/                                   a repeated run, optimizer random
    EXP/state.json                                       wall times per repetition
    EXP/report.md, report.json, *.png                    the report, rewritten after each repetition

The kind of a run is its own ``config.yaml``'s ``optimizer`` setting ("mobo" or one of Optuna's
samplers: an optimizer, "random": uniform random search), never the folder's name.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

from mjxskill._files import is_regular
from mjxskill.errors import RunError
from mjxskill.runs.run_dir import CONFIG, Run
from mjxskill.runs.settings import BOTORCH_OPTIMIZERS, OPTUNA_OPTIMIZERS

EXPERIMENT = "experiment.yaml"
OPTIMIZER_RUNS = "optimizer"
RANDOM_RUNS = "random_search"
# config.yaml's optimizer -> kind; Optuna's samplers are optimizers like ours to the layouts
KINDS = {"mobo": "optimizer", "random": "random_search",
         **{name: "optimizer" for name in OPTUNA_OPTIMIZERS + BOTORCH_OPTIMIZERS}}


class RunRef(NamedTuple):
    """kind: "optimizer" or "random_search"; seed: the run's seed; path: its run directory."""

    kind: str
    seed: int
    path: Path


def directory_kind(path: Path | str) -> str:
    """"experiment", "repeated" or "run"; RunError when ``path`` is none of them."""
    path = Path(path)
    if is_regular(path / EXPERIMENT, RunError):
        return "experiment"
    if is_regular(path / CONFIG, RunError):
        return "repeated" if Run(path).config().repeats > 1 else "run"
    raise RunError(f"{path} is not a run directory (no {CONFIG}) nor an experiment (no {EXPERIMENT})")


def experiment_holding(path: Path | str) -> Path | None:
    """The experiment directory that ``path`` (EXP/optimizer, EXP/random_search or one of their
    seed-<s> runs) belongs to; None for a run or repeated run of its own (or an experiment)."""
    # As written (EXP/optimizer may be a link to storage elsewhere) and with links resolved (a
    # link to EXP/optimizer/seed-0).
    for where in (Path(os.path.abspath(path)), Path(path).resolve()):
        for member in (where, where.parent):  # the repeated run, or the run inside it
            if member.name in (OPTIMIZER_RUNS, RANDOM_RUNS) and (member.parent / EXPERIMENT).is_file():
                return member.parent
    return None


def runs_in(path: Path | str) -> list[RunRef]:
    """Every run ``path`` holds, in seed order (an experiment: its optimizer runs, then its
    random searches). RunError when ``path`` is no run, repeated run or experiment."""
    path = Path(path)
    kind = directory_kind(path)
    if kind == "experiment":
        return [*runs_in(path / OPTIMIZER_RUNS), *runs_in(path / RANDOM_RUNS)]
    run = Run(path)
    config = run.config()
    subs = run.sub_runs(config) if kind == "repeated" else [run]
    refs = []
    for sub in subs:
        own = sub.config() if sub is not run else config
        refs.append(RunRef(KINDS[own.optimizer], own.seed, sub.path))
    return refs


__all__ = ["EXPERIMENT", "KINDS", "OPTIMIZER_RUNS", "RANDOM_RUNS", "RunRef", "directory_kind", "experiment_holding", "runs_in"]
