"""The evaluations of repeated runs pooled: one picked solution per run, groups, tests.

**The pick** (stated in every report): per run, the Pareto solution of its *training* front
with the highest training success rate among those whose COMMANDED force
(``peak_commanded_force``: the largest feed-forward force the skills command in an episode,
mean over the training worlds) is at most the bound, ties broken by the higher first objective
(``mjxskill.evaluation.selection.choose``'s rule, but on the commanded force: ``select
--max-force`` bounds the measured contact force). The bound is the one the command gives
(``--max-force``), else the scenario's ``pick.max_force`` with its reason (``force_bound``);
without either the pick is unbounded. It is a number someone states, not one derived from the
operators' sets: those are illustrative examples, and a bound read off them excluded robust
solutions that pressed a little harder than the hardest-pressing example.
The pick reads only the training front, as an operator would; its evaluation is its row in the
run's evaluation. **Validated** (an experiment's default, ``mjxskill.evaluation.validation``): the
K solutions within the bound with the highest training success are rolled out again in fresh
worlds of the known start configurations, and the highest success there decides (ties: the
lower mean time to success there, a failure counted as the full episode; then the training
success, then the first objective), so that a knife-edge set that was lucky in its few
training worlds is not picked over a robust one.

**The samples** of a group (Mann-Whitney U, box plots): one success rate per (run, candidate,
start configuration), the unit ``evaluate`` uses for one run. The picked group has one
candidate per run, so R runs give R x C samples (C known or unseen start configurations): with
R = 3 one sample per run would be too few for the test (its smallest two-sided p is 0.1).
Samples of one run share its worlds, so they are not independent: the p-values say how the
success rates differ across start configurations and runs, not across fresh experiments.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mjxskill.errors import RunError
from mjxskill.evaluation.baselines import (
    GROUP_LABELS,
    GROUPS,
    Evaluation,
    box_plot,
    mean_success_seconds,
    significance,
    stars_of,
)

POOLED_GROUPS = ("picked", *GROUPS)
POOLED_LABELS = {"picked": "picked (learned)", **GROUP_LABELS}
BASELINES = ("planner", "random", "manual")
TESTED = ("pareto", *BASELINES)  # what the picked solutions are tested against: the baselines and their own fronts


class Pick(NamedTuple):
    """row: the picked row of pareto.csv (None: no Pareto solution within the bound); bound: the
    force bound in N (None: none); source: where the bound came from, in words."""

    row: int | None
    bound: float | None
    source: str


GIVEN = "given (--max-force)"


def force_bound(max_force: float | None, stated=None) -> tuple[float | None, str]:
    """The pick's bound on the commanded force, N, and where it comes from: ``max_force`` (the
    command's) when given, else ``stated`` (the scenario's ``PickBound``), else none."""
    if max_force is not None:
        return float(max_force), GIVEN
    if stated is not None:
        return float(stated.max_force), f"the scenario's pick.max_force: {stated.why}"
    return None, "none (the scenario states no pick.max_force and none was given)"


def pick(front, ev: Evaluation, max_force: float | None = None, validation=None, source: str | None = None,
         race=None) -> Pick:
    """The picked Pareto solution of a run (``front``: its training Pareto rows, the ones ``ev``
    evaluated as ``pareto-<k>``) within ``max_force`` N of commanded force (None: unbounded;
    ``source``: where that bound comes from, default ``force_bound``'s words for a bound
    given or none). ``validation``
    (``mjxskill.evaluation.validation.Validation`` of the rows :func:`contenders` names): the
    highest validation success among them decides. ``race`` (a run of the robust protocol,
    ``mjxskill.evaluation.racing.Race`` within that bound): its winner is the pick."""
    check_front(front, ev)
    bound = None if max_force is None else float(max_force)
    source = force_bound(bound)[1] if source is None else source
    if race is not None:
        return Pick(race.winner, bound, source)
    if validation is None:
        return Pick(choose_commanded(front, bound), bound, source)
    rows = contenders(front, bound, validation.candidates or len(validation.rows))
    if list(rows) != list(validation.rows):
        raise RunError("the validation is not of the Pareto solutions in contention: validate the run again")
    if not rows:
        return Pick(None, bound, source)
    return Pick(validated_best(front, rows, validation), bound, source)


def validated_best(front, rows, validation) -> int:
    """The row of ``front`` a validated pick takes among the contenders ``rows`` (non-empty,
    in ``validation``'s order): the highest validation success; of equal ones the faster
    (failures as full episodes), then the training success, then the first objective."""
    r = np.asarray(rows)
    seconds = np.zeros(len(r)) if validation.seconds is None else np.nan_to_num(validation.seconds, nan=np.inf)
    order = np.lexsort((-front.objectives[r, 0], -front.success_rate[r], seconds, -np.asarray(validation.success)))
    return int(r[order[0]])


def check_front(front, ev: Evaluation) -> None:
    pareto = [i for i, g in enumerate(ev.candidates.groups) if g == "pareto"]
    if len(pareto) != len(front) or not np.array_equal(ev.candidates.params[pareto], front.params):
        raise RunError("the evaluation is not of the run's current Pareto front: evaluate the run again")


def contenders(front, bound: float | None, n: int) -> list[int]:
    """The ``n`` rows of ``front`` within ``bound`` (None: all) with the best training success,
    ties by the first objective, best first (fewer when fewer are within the bound)."""
    ok = np.ones(len(front), bool) if bound is None else front.peak_commanded_force <= bound  # NaN: not within
    rows = np.flatnonzero(ok)
    order = np.lexsort((-front.objectives[rows, 0], -front.success_rate[rows]))
    return [int(r) for r in rows[order[:n]]]


def choose_commanded(front, bound: float | None) -> int | None:
    """The row of ``front`` with the best success rate, ties by the first objective, among those
    whose peak_commanded_force is at most ``bound`` (None: all); None when no row is."""
    best = contenders(front, bound, 1)
    return best[0] if best else None


def picked_row(ev: Evaluation, p: Pick) -> int | None:
    """The row of ``ev`` that holds the picked solution."""
    return None if p.row is None else ev.candidates.names.index(f"pareto-{p.row}")


def group_rows(ev: Evaluation, group: str, p: Pick) -> list[int]:
    if group == "picked":
        row = picked_row(ev, p)
        return [] if row is None else [row]
    return [i for i, g in enumerate(ev.candidates.groups) if g == group]


def pooled_samples(evals: list[Evaluation], picks: list[Pick]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """group -> (known samples, unseen samples) over every run (see the module docstring)."""
    out = {}
    for group in POOLED_GROUPS:
        known, unseen = [], []
        for ev, p in zip(evals, picks):
            rows = group_rows(ev, group, p)
            # numpy's stubs take arrays for np.ix_; a list of row indices is one
            known.append(ev.success[np.ix_(rows, ev.known)].ravel())  # type: ignore[arg-type]
            unseen.append(ev.success[np.ix_(rows, ~ev.known)].ravel())  # type: ignore[arg-type]
        if any(len(k) or len(u) for k, u in zip(known, unseen)):
            out[group] = (np.concatenate(known), np.concatenate(unseen))
    return out


def pooled_tests(samples: dict) -> dict[str, dict[str, float | None]]:
    """group -> {"known": p, "unseen": p}: two-sided Mann-Whitney U of the picked samples
    against each baseline's and the whole Pareto group's (None where a side has no samples)."""
    tests: dict[str, dict[str, float | None]] = {}
    if "picked" not in samples:
        return tests
    for baseline in TESTED:
        if baseline not in samples:
            continue
        tests[baseline] = {side: (significance(samples["picked"][i], samples[baseline][i])[0]
                                  if len(samples["picked"][i]) and len(samples[baseline][i]) else None)
                           for i, side in enumerate(("known", "unseen"))}
    return tests


def group_means(samples: dict) -> dict[str, dict[str, float | None]]:
    """group -> {"known": mean success rate, "unseen": ...} (None: no samples)."""
    return {g: {side: float(np.mean(v[i])) if len(v[i]) else None for i, side in enumerate(("known", "unseen"))}
            for g, v in samples.items()}


def group_force_and_time(evals: list[Evaluation], picks: list[Pick], group: str) -> tuple[float, float]:
    """(mean commanded force N over the group's candidates, mean time to success s over their
    successful worlds) pooled over the runs; NaN where not measured."""
    forces: list[float]
    forces, weighted, weights = [], 0.0, 0.0
    for ev, p in zip(evals, picks):
        rows = group_rows(ev, group, p)
        if ev.peak_commanded_force is not None:
            forces.extend(ev.peak_commanded_force[rows])
        seconds = mean_success_seconds(ev, rows) if rows else float("nan")
        if np.isfinite(seconds):
            n = float(ev.success[rows].sum())
            weighted, weights = weighted + seconds * n, weights + n
    force = float(np.mean(forces)) if forces else float("nan")
    return force, (weighted / weights if weights else float("nan"))


def full_episode_seconds(evals: list[Evaluation], picks: list[Pick], group: str, episode_seconds: float) -> float:
    """Mean time to success over every world of the group's candidates pooled over the runs, a
    world that did not succeed (or whose tree never returned SUCCESS) counted as the full episode
    ``episode_seconds``: a group that fails more is slower, where the mean over its successes
    alone would count only the fast ones. NaN: no run has per-world times."""
    times: list[np.ndarray] | np.ndarray = [np.where(np.isfinite(t), t, episode_seconds).ravel()
             for ev, p in zip(evals, picks) if ev.world_seconds is not None
             for t in [ev.world_seconds[group_rows(ev, group, p)]]]
    times = np.concatenate(times) if times else np.zeros(0)
    return float(times.mean()) if len(times) else float("nan")


def paired_seconds(evals: list[Evaluation], picks: list[Pick], group: str, other: str) -> tuple[float, float, int]:
    """(mean time to success of ``group``, of ``other``, number of pairs) over the worlds where a
    candidate of each succeeded: every (run, world, candidate of group, candidate of other) with
    both successful is one pair, so both means are over the same worlds. NaN, NaN, 0: no pair
    (or no per-world times)."""
    a_all, b_all = [], []
    for ev, p in zip(evals, picks):
        if ev.world_seconds is None:
            continue
        for i in group_rows(ev, group, p):
            for j in group_rows(ev, other, p):
                a, b = ev.world_seconds[i].ravel(), ev.world_seconds[j].ravel()
                both = np.isfinite(a) & np.isfinite(b)
                a_all.append(a[both])
                b_all.append(b[both])
    a = np.concatenate(a_all) if a_all else np.zeros(0)
    b = np.concatenate(b_all) if b_all else np.zeros(0)
    if not len(a):
        return float("nan"), float("nan"), 0
    return float(a.mean()), float(b.mean()), int(len(a))


def plot_pooled(samples: dict, path, title: str, *, root=None) -> dict:
    """Box plots of the pooled groups, picked against each (into ``path`` below ``root``, the
    run); returns box_plot's tests."""
    labelled = {POOLED_LABELS[g]: v for g, v in samples.items()}
    return box_plot(labelled, POOLED_LABELS["picked"], path, title, root=root)


def pooled_table(samples: dict, tests: dict) -> str:
    """Mean success per group and the picked solutions' p-values against each baseline."""
    means = group_means(samples)
    lines = [f"{'group':<24} {'known':>6} {'unseen':>7}  samples  Mann-Whitney U, picked vs group"]
    for g, (known, unseen) in samples.items():
        m = means[g]
        cells = [f"{v:>6.0%}" if v is not None else f"{'-':>6}" for v in (m["known"], m["unseen"])]
        note = ", ".join(f"{side} p={p:.3g} {stars_of(p)}" for side, p in tests.get(g, {}).items() if p is not None)
        lines.append(f"{POOLED_LABELS[g]:<24} {cells[0]} {cells[1]:>7}  {len(known):>3}+{len(unseen):<3}  {note}")
    return "\n".join(lines)


__all__ = ["BASELINES", "GIVEN", "POOLED_GROUPS", "POOLED_LABELS", "TESTED", "Pick", "check_front", "choose_commanded", "contenders", "force_bound", "full_episode_seconds", "group_force_and_time", "group_means",
           "paired_seconds",
           "pick", "picked_row", "plot_pooled", "pooled_samples", "pooled_table", "pooled_tests", "validated_best"]
