"""The learned Pareto solutions of a run against baselines (``python -m mjxskill.evaluate``).

Candidates: every Pareto solution of the run (``pareto-<k>``, k = row of pareto.csv), the
planner-only parameters (the skill defaults), ``--random`` uniform parameter sets, and the
manual parameter sets of the scenario (operators' choices). Each runs ``--per-config`` worlds
from every start configuration: the known ones (training) and the unseen ones (evaluation
only), all in one compiled call of the same explicit worlds for every candidate.

Writes ``RUN_DIR/evaluation/``: ``evaluation.csv`` (one row per candidate, success rate per
start configuration), ``success.png`` (box plots like the paper's: one sample per candidate and
start configuration, Mann-Whitney U of the Pareto group against each baseline group with
stars * p<0.05, ** p<0.01, *** p<0.001, ns otherwise), and prints the table.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np


GROUPS = ("pareto", "planner", "random", "manual")
GROUP_LABELS = {"pareto": "Pareto (learned)", "planner": "planner only", "random": "random", "manual": "operators"}


class Candidates(NamedTuple):
    """names (N,), groups (N,) one of GROUPS, params (N, P)."""

    names: tuple[str, ...]
    groups: tuple[str, ...]
    params: np.ndarray


class Evaluation(NamedTuple):
    """success (N, C) success rate of each candidate from each start configuration; known (C,)
    bool: a training configuration (else unseen); config_names (C,); position_error (N, C)
    mean final position error of the task's object, m (how close a failure came)."""

    candidates: Candidates
    success: np.ndarray
    known: np.ndarray
    config_names: tuple[str, ...]
    position_error: np.ndarray | None = None

    def mean(self, known: bool) -> np.ndarray:
        """(N,) mean success over the known (or the unseen) configurations."""
        cols = self.known if known else ~self.known
        return self.success[:, cols].mean(axis=1) if cols.any() else np.full(len(self.success), np.nan)


def build_candidates(task, pareto_params: np.ndarray, n_random: int, seed: int) -> Candidates:
    """Pareto rows, the planner-only defaults, ``n_random`` uniform sets, the manual sets of
    ``task`` (a ``mjxskill.task.PlannedTask``)."""
    lo, hi = np.asarray(task.bounds, np.float64)
    rng = np.random.default_rng([seed, 0xE7A1])
    random = lo + rng.random((n_random, len(lo))) * (hi - lo)
    manual = dict(task.manual_parameters)
    names = ([f"pareto-{k}" for k in range(len(pareto_params))] + ["planner"]
             + [f"random-{i}" for i in range(n_random)] + list(manual))
    groups = ["pareto"] * len(pareto_params) + ["planner"] + ["random"] * n_random + ["manual"] * len(manual)
    params = np.concatenate([np.reshape(pareto_params, (-1, len(lo))), np.asarray(task.defaults, np.float64)[None],
                             random, np.reshape(np.array(list(manual.values()), np.float64), (-1, len(lo)))])
    return Candidates(tuple(names), tuple(groups), params)


def evaluation_worlds(rollout, per_config: int, seed: int):
    """The worlds every candidate runs in: ``per_config`` from each known, then each unseen
    start configuration (configuration-major, leading shape (C * per_config,)). Returns
    (worlds, config_names (C,), known (C,) bool)."""
    import jax

    scn = rollout.scenario
    known_cfg, unseen_cfg = np.asarray(scn.robot.start_configs), np.asarray(scn.robot.eval_configs)
    key_known, key_unseen = jax.random.split(jax.random.fold_in(jax.random.PRNGKey(seed), 0xE7A1))
    parts = [rollout.worlds_per_config(key_known, per_config, known_cfg)]
    if len(unseen_cfg):
        parts.append(rollout.worlds_per_config(key_unseen, per_config, unseen_cfg))
    worlds = jax.tree.map(lambda *xs: np.concatenate([np.asarray(x) for x in xs]), *parts)
    names = tuple([f"known-{i}" for i in range(len(known_cfg))] + [f"unseen-{j}" for j in range(len(unseen_cfg))])
    known = np.array([True] * len(known_cfg) + [False] * len(unseen_cfg))
    return worlds, names, known


def evaluate_candidates(rollout, candidates: Candidates, per_config: int, seed: int, batch_size: int) -> Evaluation:
    """Runs every candidate in the same per-configuration worlds (known + unseen configs)."""
    worlds, names, known = evaluation_worlds(rollout, per_config, seed)
    n_cfg = len(names)
    rows, errors = [], []
    params = candidates.params
    for start in range(0, len(params), batch_size):
        chunk = params[start : start + batch_size]
        padded = np.concatenate([chunk, np.repeat(chunk[:1], batch_size - len(chunk), axis=0)])
        out = rollout.run_worlds(padded, worlds)
        success = np.asarray(out.success, np.float64)[: len(chunk)]  # (b, n_cfg * per_config)
        rows.append(success.reshape(len(chunk), n_cfg, per_config).mean(axis=2))
        metrics = getattr(out, "metrics", None) or {}
        if "position_error" in metrics:
            error = np.asarray(metrics["position_error"], np.float64)[: len(chunk)]
            errors.append(error.reshape(len(chunk), n_cfg, per_config).mean(axis=2))
    position_error = np.concatenate(errors) if len(errors) == len(rows) else None
    return Evaluation(candidates, np.concatenate(rows), known, names, position_error)


def significance(a: np.ndarray, b: np.ndarray) -> tuple[float, str]:
    """Two-sided Mann-Whitney U p-value of samples a vs b and its stars."""
    from scipy.stats import mannwhitneyu

    if len(a) == 0 or len(b) == 0 or (np.all(a == a[0]) and np.all(b == a[0])):
        return 1.0, "ns"  # identical samples: no evidence of a difference
    p = float(mannwhitneyu(a, b, alternative="two-sided").pvalue)
    stars = "***" if p < 0.001 else "**" if p < 0.01 else "*" if p < 0.05 else "ns"
    return p, stars


def group_samples(ev: Evaluation, group: str, known: bool) -> np.ndarray:
    """Success rates of ``group``: one sample per (candidate, start configuration)."""
    rows = np.array([g == group for g in ev.candidates.groups])
    cols = ev.known if known else ~ev.known
    return ev.success[np.ix_(rows, cols)].ravel()


def plot_boxes(ev: Evaluation, path: Path, title: str) -> dict:
    """Box plots per group, known and unseen side by side, with significance stars; returns the
    tests {(known|unseen, group): (p, stars)}."""
    from mjxskill.training.report import pyplot

    plt = pyplot()
    present = [g for g in GROUPS if g in ev.candidates.groups]
    panels = [("known", True)] + ([("unseen", False)] if (~ev.known).any() else [])
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.4), sharey=True, squeeze=False)
    tests = {}
    for ax, (label, known) in zip(axes[0], panels):
        data = [group_samples(ev, g, known) for g in present]
        ax.boxplot(data, showmeans=True)
        ax.set_xticks(range(1, len(present) + 1), [GROUP_LABELS[g] for g in present], rotation=15)
        ax.set_title(f"{label} start configurations")
        ax.set_ylim(-0.05, 1.25)
        ref = data[present.index("pareto")] if "pareto" in present else None
        for k, g in enumerate(present):
            if g == "pareto" or ref is None:
                continue
            p, stars = significance(ref, data[k])
            tests[(label, g)] = (p, stars)
            ax.text(k + 1, 1.1, stars, ha="center", fontsize=11)
    axes[0][0].set_ylabel("success rate (fraction of worlds)")
    fig.suptitle(title + "  (Mann-Whitney U vs Pareto)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return tests


def write_csv(ev: Evaluation, parameter_names: Sequence[str], path: Path) -> None:
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        err = ev.position_error
        writer.writerow(["candidate", "group", *parameter_names, "success_known", "success_unseen",
                         *(f"success_{c}" for c in ev.config_names)]
                        + ([] if err is None else ["position_error_known_m", "position_error_unseen_m"]))
        known, unseen = ev.mean(True), ev.mean(False)
        for i, name in enumerate(ev.candidates.names):
            extra = [] if err is None else [repr(float(err[i, ev.known].mean())), repr(float(err[i, ~ev.known].mean()) if (~ev.known).any() else "nan")]
            writer.writerow([name, ev.candidates.groups[i], *map(repr, map(float, ev.candidates.params[i])),
                             repr(float(known[i])), repr(float(unseen[i])), *map(repr, map(float, ev.success[i]))] + extra)


def table(ev: Evaluation, tests: dict) -> str:
    """Per-candidate table and per-group summary with the significance tests."""
    head = ["candidate", "group", "known", "unseen", *ev.config_names]
    known, unseen = ev.mean(True), ev.mean(False)
    rows = [[n, g, f"{known[i]:.0%}", f"{unseen[i]:.0%}", *(f"{v:.0%}" for v in ev.success[i])]
            for i, (n, g) in enumerate(zip(ev.candidates.names, ev.candidates.groups))]
    if ev.position_error is not None:  # mean final object position error over all configurations
        head.append("pos.err [mm]")
        for i, row in enumerate(rows):
            row.append(f"{1000 * ev.position_error[i].mean():.0f}")
    widths = [max(len(r[c]) for r in [head, *rows]) for c in range(len(head))]
    fmt = lambda r: "  ".join(x.ljust(w) if c < 2 else x.rjust(w) for c, (x, w) in enumerate(zip(r, widths)))  # noqa: E731
    lines = [fmt(head), *map(fmt, rows), "", "group              known  unseen  (mean success; Mann-Whitney U vs Pareto)"]
    for g in GROUPS:
        if g not in ev.candidates.groups:
            continue
        k, u = group_samples(ev, g, True), group_samples(ev, g, False)
        note = "" if g == "pareto" else "  " + ", ".join(
            f"{lab} p={tests[(lab, g)][0]:.3g} {tests[(lab, g)][1]}" for lab in ("known", "unseen") if (lab, g) in tests)
        lines.append(f"{GROUP_LABELS[g]:<18} {k.mean():>5.0%}  {u.mean() if len(u) else float('nan'):>6.0%}{note}")
    return "\n".join(lines)
