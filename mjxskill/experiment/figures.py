"""The experiment's figures (matplotlib, Agg): the fronts of every repetition, hypervolume against
evaluations (optimizer vs random search, median and quartiles), and the success box plots."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mjxskill.training.front import pareto_mask_of
from mjxskill._headless import pyplot
from mjxskill.training.report import objective_label
from mjxskill.runs.atomic_write import save_figure

FRONTS = "fronts.png"
HYPERVOLUME = "hypervolume.png"
SUCCESS = "success.png"


def plot_fronts(reps, objective_names, task: str, path: Path) -> None:
    """One panel per kind (optimizer, random search), one colour per repetition (paper Fig. 3, 5)."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11.5, 4.8), sharex=True, sharey=True)
    cmap = plt.get_cmap("tab10" if len(reps) <= 10 else "tab20")
    j = 1 if len(objective_names) > 1 else 0
    for ax, kind, title in zip(axes, ("optimizer", "random_search"), ("Bayesian optimizer", "random search")):
        sizes = []
        for k, r in enumerate(reps):
            ev = getattr(r, kind)
            front = ev.objectives[pareto_mask_of(ev)]
            sizes.append(len(front))
            order = np.argsort(front[:, 0])
            ax.plot(front[order, 0], front[order, j], "o-", color=cmap(k % cmap.N), ms=4, label=f"seed {r.seed} ({len(front)})")
        mean = f", mean size {np.mean(sizes):.1f}" if sizes else ""
        ax.set_title(f"{title}: Pareto fronts of {len(reps)} repetitions{mean}", fontsize=10)
        ax.set_xlabel(objective_label(objective_names[0]))
        ax.legend(loc="best", fontsize="small")
    axes[0].set_ylabel(objective_label(objective_names[j]))
    fig.suptitle(f"{task}: one colour per repetition", fontsize=11)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def plot_hypervolume(hv: dict, n_init: int, task: str, path: Path) -> None:
    """Median and quartiles over the repetitions of the normalized hypervolume per kind."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.8, 4.4))
    x = np.asarray(hv.get("evaluations", []), np.float64)
    for kind, label, color in (("optimizer", "Bayesian optimizer", "tab:blue"), ("random_search", "random search", "tab:orange")):
        curves = np.asarray(hv.get("curves", {}).get(kind, []), np.float64)
        if not curves.size:
            continue
        q1, med, q3 = np.percentile(curves, [25, 50, 75], axis=0)
        ax.plot(x, med, "-", color=color, label=f"{label} (median of {len(curves)})")
        ax.fill_between(x, q1, q3, color=color, alpha=0.25, lw=0)
    ax.axvline(n_init, color="gray", ls="--", lw=1, label="end of the shared random warm-up")
    ax.set_xlabel("evaluations (parameter sets)")
    ax.set_ylabel("hypervolume (normalized objectives)")
    ref = hv.get("reference_point")
    ax.set_title(f"{task}: hypervolume, median and quartiles over repetitions\n(objectives scaled by all runs' "
                 f"min/max, reference {ref})", fontsize=9)
    ax.legend(loc="lower right", fontsize="small")
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


__all__ = ["FRONTS", "HYPERVOLUME", "SUCCESS", "plot_fronts", "plot_hypervolume"]
