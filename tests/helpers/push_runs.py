"""Run directories of the push task as ``train`` writes them, without training them, and a Pareto
front written into one: the inputs of the tests that hand a run to a command (bad input, bounds,
a full disk, a changed scenario, the pooled evaluation)."""

import numpy as np

from mjxskill.runs.run_dir import PARETO, Evaluations, Run, RunConfig, write_csv
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task, planning_texts


def push_run(folder, **settings) -> Run:
    """A run directory of the push task as ``train`` writes it, without training it."""
    scn = load_scenario("push")
    task = plan_task(scn)
    values = dict(budget=4, batch_size=2, n_init=2, worlds=1, seed=0, episode_seconds=0.2)
    values.update(settings)
    config = RunConfig(task="push", scenario="push", goal=task.goal, parameter_names=task.parameter_names,
                       parameter_units=task.parameter_units, bounds=tuple(tuple(map(float, b)) for b in task.bounds),
                       objective_names=scn.objective_names, **values)
    run = Run(folder)
    run.create(config, scn.source, planning_texts(task))
    return run


def front_rows(run: Run, n: int, peak_force=None) -> None:
    """``n`` Pareto rows in pareto.csv of ``run`` (peak_force: their peak contact forces, NaN allowed)."""
    config = run.config()
    rng = np.random.default_rng(0)
    lo, hi = np.asarray(config.bounds)
    ev = Evaluations(np.zeros(n, int), lo + rng.random((n, len(lo))) * (hi - lo), rng.normal(size=(n, 2)),
                     np.full(n, 0.5), np.asarray(peak_force if peak_force is not None else np.full(n, 3.0), float),
                     np.full(n, 1.0), np.full(n, 7.0))
    write_csv(run.path / PARETO, config.columns(), ev)
