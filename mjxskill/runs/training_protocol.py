"""How a run spends its episodes: the paper's protocol, or the robust one.

**paper** (every run before the setting): each evaluation is a new parameter set rolled out
in its batch's ``worlds`` fresh worlds, the objectives are the scenario's, and what a run
ends with is its front.

**robust** (the default of a new run): seven worlds cannot tell a robust parameter set from a
lucky one (one that succeeds in 80 % of worlds passes 7 of 7 with probability 0.21), and
among sets tied at 7 of 7 the paper's objectives prefer the fast, gentle, fragile ones
(docs/experiments/peg/README.md). So

* the success rate is an objective of its own, ``SUCCESS_OBJECTIVE``: the lower bound of its
  Beta posterior over the worlds a parameter set was rolled out in (``success_lower_bound``),
  so that 7 of 7 ranks below 28 of 28;
* after the warm-up, ``REPLICATIONS_PER_BATCH`` places of every batch roll a parameter set
  out again in that batch's fresh worlds (the set the success model believes best, up to
  ``MAX_WORLDS_FACTOR`` x worlds: mjxskill.training.replication), and its row is replaced by
  one that pools all its worlds (evaluations.csv: ``worlds``, ``replaces``, ``sd_<objective>``);
  the optimizer fits each row's mean with its own noise (its world-to-world spread over its
  number of worlds);
* the pick races the front (mjxskill.evaluation.racing): the front's members within the force
  bound get fresh worlds from the known start configurations in rounds, the worse half
  dropped after each.

The episodes a run spends are counted in one budget, ``EPISODE_SHARE`` x budget x worlds, the
paper's budget with 15 % more: training takes ``TRAINING_SHARE`` x budget evaluations (new sets
and sets rolled out again, ``worlds`` worlds each), the race the rest. The split was measured:
among the front of a peg run, the race's pick succeeded in 94.4 % of 600 fresh worlds (the
mean over 400 simulated races) with the 420 episodes left beside 400 evaluations, in 95.4 % with
980 and 95.8 % with 1400, where the front's best reached 96.2 % and the best operator set
94.7 % (benchmarks/RESULTS.md, "The robust protocol").
"""

from __future__ import annotations

import numpy as np

from mjxskill.errors import ScenarioError

PROTOCOLS = ("robust", "paper")
SUCCESS_OBJECTIVE = "success_lower_bound"
# The success objective's bound: this quantile of the Beta(s + 1/2, n - s + 1/2) posterior of
# s successes in n worlds (Jeffreys' prior): 7 of 7 -> 0.768, 28 of 28 -> 0.934.
BOUND_QUANTILE = 0.05
REPLICATIONS_PER_BATCH = 1
MAX_WORLDS_FACTOR = 4  # a parameter set is rolled out in at most this many times ``worlds`` worlds
EPISODE_SHARE = 1.15  # the episodes a robust run spends, of the paper protocol's budget x worlds
TRAINING_SHARE = 0.75  # the evaluations it trains with, of the budget (the race has the rest)


def objective_names(scenario_objectives, protocol: str) -> tuple[str, ...]:
    """A run's objectives: the scenario's, and under the robust protocol the success bound
    (ScenarioError when the scenario has an objective of that name already)."""
    names = tuple(scenario_objectives)
    if protocol != "robust":
        return names
    if SUCCESS_OBJECTIVE in names:
        raise ScenarioError(f"the scenario's objective {SUCCESS_OBJECTIVE!r} has the name of the objective the robust "
                            "protocol adds (the success rate's lower bound): rename it in the scenario's objectives "
                            "and rewards, or train with --protocol paper")
    return names + (SUCCESS_OBJECTIVE,)


def success_lower_bound(successes, worlds, quantile: float = BOUND_QUANTILE) -> np.ndarray:
    """The ``quantile`` of the Beta(s + 1/2, n - s + 1/2) posterior of the success rate after
    ``successes`` s in ``worlds`` n (arrays broadcast; s, n may be fractional, a rate times a
    world count)."""
    from scipy.special import betaincinv  # lazy: scipy.special costs ~0.2 s; the CLIs' --help import this module

    s, n = np.asarray(successes, np.float64), np.asarray(worlds, np.float64)
    return betaincinv(s + 0.5, n - s + 0.5, quantile)


def success_upper_bound(successes, worlds, quantile: float = BOUND_QUANTILE) -> np.ndarray:
    """The ``1 - quantile`` quantile of the same posterior."""
    return success_lower_bound(successes, worlds, 1.0 - quantile)


def training_rows(budget: int, protocol: str) -> int:
    """The evaluations a run trains with: its budget (paper), TRAINING_SHARE of it (robust)."""
    return budget if protocol != "robust" else max(1, int(TRAINING_SHARE * budget + 0.5))


def race_episodes(budget: int, worlds: int) -> int:
    """The episodes the robust protocol's race may spend: what EPISODE_SHARE x budget x worlds
    leaves beside training."""
    return max(0, int(EPISODE_SHARE * budget * worlds + 1e-9) - training_rows(budget, "robust") * worlds)


def pooled_moments(n_a, mean_a, sd_a, n_b, mean_b, sd_b) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n, mean, sd) of two groups of per-world values joined, from each group's count, mean and
    sample standard deviation (ddof 1; NaN or anything for a group of one), exactly as of the
    values themselves (Chan et al.'s parallel variance)."""
    n_a, n_b = np.asarray(n_a, np.float64), np.asarray(n_b, np.float64)
    mean_a, mean_b = np.asarray(mean_a, np.float64), np.asarray(mean_b, np.float64)
    m2_a = np.where(n_a > 1, np.nan_to_num(np.asarray(sd_a, np.float64)) ** 2 * (n_a - 1), 0.0)
    m2_b = np.where(n_b > 1, np.nan_to_num(np.asarray(sd_b, np.float64)) ** 2 * (n_b - 1), 0.0)
    n = n_a + n_b
    delta = mean_b - mean_a
    mean = mean_a + delta * n_b / n
    m2 = m2_a + m2_b + delta**2 * n_a * n_b / n
    sd = np.where(n > 1, np.sqrt(np.maximum(m2, 0.0) / np.maximum(n - 1, 1)), np.nan)
    return n, mean, sd


__all__ = ["BOUND_QUANTILE", "EPISODE_SHARE", "MAX_WORLDS_FACTOR", "PROTOCOLS", "REPLICATIONS_PER_BATCH",
           "SUCCESS_OBJECTIVE", "TRAINING_SHARE", "objective_names", "pooled_moments", "race_episodes",
           "success_lower_bound", "success_upper_bound", "training_rows"]
