"""Small run directories of the push task for the explore tests, written with the run-directory
API (no training): the push task's real parameters, units, bounds and objectives, and made-up
evaluations with a trade-off between the two objectives."""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from mjxskill.runs.run_dir import Evaluations, Run, RunConfig, batch_sizes
from mjxskill.scenario import scenario_path
from mjxskill.training.front import pareto_mask_of

BUDGET, BATCH, N_INIT = 30, 6, 12


@lru_cache(maxsize=1)
def push_config() -> RunConfig:
    from mjxskill.scenario import load_scenario
    from mjxskill.task import plan_task

    scn = load_scenario("push")
    task = plan_task(scn)
    lo, hi = np.asarray(task.bounds, np.float64)
    return RunConfig(task=scn.name, scenario="push", goal=scn.goal, parameter_names=tuple(task.parameter_names),
                     parameter_units=tuple(task.parameter_units), bounds=(tuple(map(float, lo)), tuple(map(float, hi))),
                     objective_names=tuple(scn.objective_names), budget=BUDGET, batch_size=BATCH, n_init=N_INIT,
                     worlds=4, seed=0, episode_seconds=2.0)


def evaluations(config: RunConfig, seed: int) -> Evaluations:
    rng = np.random.default_rng(seed)
    sizes = list(batch_sizes(config.budget, config.batch_size, config.n_init))
    iteration = np.repeat(np.arange(len(sizes)), sizes)
    lo, hi = np.asarray(config.bounds)
    params = lo + rng.random((config.budget, len(lo))) * (hi - lo)
    success = rng.integers(0, config.worlds + 1, config.budget) / config.worlds
    force = rng.uniform(1.0, 30.0, config.budget)
    objectives = np.stack([700 * success - 40 * rng.random(config.budget), 120 - 3 * force + rng.random(config.budget)], axis=1)
    # force: the measured peak contact force; its mean and the commanded force are made up beside it
    return Evaluations(iteration, params, objectives, success, force, force / 4, np.minimum(force, 7.0))


def write_run(run: Run, config: RunConfig, seed: int, create: bool = True) -> Evaluations:
    if create:
        run.path.parent.mkdir(parents=True, exist_ok=True)
        run.create(config, str(scenario_path("push")), {"plan.txt": "(GoToLinear) (Push)"})
    ev = evaluations(config, seed)
    run.append(ev)
    run.write_pareto(config, ev, pareto_mask_of(ev))
    return ev


def make_push_run(path: Path, seed: int = 0) -> Run:
    """A single run of 30 evaluations at ``path``."""
    run = Run(path)
    write_run(run, replace(push_config(), seed=seed), seed)
    return run


def make_repeated_run(path: Path, repeats: int = 3) -> Run:
    """A ``train --repeats`` directory: config.yaml with ``repeats`` and one sub-run per seed."""
    root = Run(path)
    config = replace(push_config(), repeats=repeats)
    path.parent.mkdir(parents=True, exist_ok=True)
    root.create(config, str(scenario_path("push")), {"plan.txt": "(GoToLinear) (Push)"})  # creates the sub-runs too
    for sub in root.sub_runs(config):
        seed = int(sub.path.name.split("-")[1])
        write_run(sub, config.sub_run(seed), seed, create=False)
    return root
