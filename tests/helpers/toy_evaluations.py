"""Hand-made evaluations (no rollout): an evaluation of Pareto rows with the success given, beside
a planner row, two random rows and the operators' rows (``toy_evaluation``), and the training
front over its first rows (``front_of``): what the pick and the experiment's bound sweep read."""

import numpy as np

from mjxskill.evaluation.baselines import Candidates, Evaluation
from mjxskill.runs.run_dir import Evaluations


def toy_evaluation(pareto_success, manual_force, pareto_force=None) -> Evaluation:
    """Pareto rows with given success (K, C); a planner row, two random rows, manual rows."""
    k, c = np.asarray(pareto_success).shape
    m = len(manual_force)
    groups = ("pareto",) * k + ("planner", "random", "random") + ("manual",) * m
    names = tuple(f"pareto-{i}" for i in range(k)) + ("planner", "random-0", "random-1") + tuple(f"op{i}" for i in range(m))
    params = np.arange(len(groups) * 2, dtype=float).reshape(-1, 2)
    success = np.concatenate([pareto_success, np.zeros((1, c)), np.full((2, c), 0.25), np.full((m, c), 0.5)])
    force = np.concatenate([np.full(k, 3.0) if pareto_force is None else pareto_force, [0.0, 1.0, 2.0], manual_force])
    return Evaluation(Candidates(names, groups, params), success, np.array([True, True, False]), ("known-0", "known-1", "unseen-0"),
                      peak_commanded_force=force)


def front_of(ev: Evaluation, success_rate, commanded_force, first_objective) -> Evaluations:
    k = len(success_rate)
    return Evaluations(np.zeros(k, int), ev.candidates.params[:k], np.stack([first_objective, -np.arange(k)], axis=1),
                       np.asarray(success_rate, float), np.full(k, np.nan), np.full(k, np.nan),
                       np.asarray(commanded_force, float))  # the pick reads the commanded force only
