"""Figures and text summaries of training runs (matplotlib, Agg backend: no display needed).

Objectives are reward sums (larger is better, no physical unit): axes say "reward". The
hypervolume is measured in the minimized space (negated objectives) against the run's fixed
reference point (see ``mjxskill.training.front``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from mjxskill._headless import pyplot
from mjxskill.runs.run_dir import Evaluations, Run, RunConfig
from mjxskill.training.front import hypervolume_history, pareto_mask_of, reference_from
from mjxskill.runs.atomic_write import save_figure, write_text

OBJECTIVE_UNIT = "reward, larger is better"


def objective_label(name: str) -> str:
    return f"objective {name} ({OBJECTIVE_UNIT})"


def plot_pareto(ev: Evaluations, mask: np.ndarray, config: RunConfig, path: Path, i: int = 0, j: int = 1) -> None:
    """All evaluations (coloured by success rate) and the Pareto front in objectives i, j."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    if len(config.objective_names) < 2:
        j = i
    sc = ax.scatter(ev.objectives[:, i], ev.objectives[:, j], c=ev.success_rate, cmap="viridis", vmin=0, vmax=1,
                    s=14, alpha=0.7, label="evaluations")
    front = ev.objectives[mask]
    order = np.argsort(front[:, i])
    ax.plot(front[order, i], front[order, j], "o-", color="crimson", mfc="none", ms=9, label=f"Pareto front ({mask.sum()})")
    fig.colorbar(sc, ax=ax, label="success rate (fraction of worlds)")
    ax.set_xlabel(objective_label(config.objective_names[i]))
    ax.set_ylabel(objective_label(config.objective_names[j]))
    ax.set_title(f"{config.task}: {len(ev)} evaluations, seed {config.seed}")
    ax.legend(loc="best")
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def plot_hypervolume(evaluations: np.ndarray, hv: np.ndarray, config: RunConfig, path: Path, n_init: int) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(evaluations, hv, "-o", ms=3)
    ax.axvline(n_init, color="gray", ls="--", lw=1, label="end of random warm-up")
    ax.set_xlabel("evaluations (parameter sets)")
    ax.set_ylabel("hypervolume (reward²)")
    ax.set_title(f"{config.task}: hypervolume of the front, seed {config.seed}\n(negated objectives, reference fixed after warm-up)", fontsize=10)
    ax.legend(loc="lower right")
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def write_run_figures(run: Run, config: RunConfig, ev: Evaluations) -> None:
    """pareto.png and hypervolume.png of one run."""
    if not len(ev):
        return
    plot_pareto(ev, pareto_mask_of(ev), config, run.path / "pareto.png")
    ref = reference_from(run, config, ev)
    if ref is not None:
        done, hv = hypervolume_history(ev, ref)
        plot_hypervolume(done, hv, config, run.path / "hypervolume.png", config.n_init)


def front_table(config: RunConfig, front: Evaluations, validated=None) -> str:
    """The Pareto solutions as a text table (index = the row of pareto.csv, used by select): the
    measured contact force's peak and mean and the commanded force, N (means over the worlds);
    with ``validated`` ((len(front),), NaN: none) a column of validation success rates."""
    names = [n.split(".")[-1] for n in config.parameter_names]
    head = ["#", *names, *(f"obj {o}" for o in config.objective_names), "success", "contact F peak/mean [N]",
            "cmd F [N]", *(["validated"] if validated is not None else [])]
    rows = [[str(k), *(f"{v:.4f}" for v in front.params[k]), *(f"{v:.2f}" for v in front.objectives[k]),
             f"{front.success_rate[k]:.0%}", f"{front.peak_contact_force[k]:.1f} / {front.mean_contact_force[k]:.1f}",
             f"{front.peak_commanded_force[k]:.1f}",
             *([] if validated is None else ["-" if np.isnan(validated[k]) else f"{validated[k]:.0%}"])]
            for k in range(len(front))]
    widths = [max(len(r[c]) for r in [head, *rows]) for c in range(len(head))]
    fmt = lambda r: "  ".join(x.rjust(w) for x, w in zip(r, widths))  # noqa: E731
    return "\n".join([fmt(head), *map(fmt, rows)])


def summary(run: Run, config: RunConfig, ev: Evaluations) -> str:
    front = ev.take(pareto_mask_of(ev))
    ref = reference_from(run, config, ev)
    hv = hypervolume_history(ev, ref)[1][-1] if ref is not None and len(ev) else float("nan")
    return (f"{run.path}: {len(ev)} evaluations, best success rate {ev.success_rate.max():.0%}, "
            f"hypervolume {hv:.4g}, Pareto front of {len(front)}:\n" + front_table(config, front))


def write_repeats(run: Run, config: RunConfig, runs: list[Run]) -> str:
    """Aggregated Pareto plot (one colour per seed) and repeats.yaml; returns a summary line."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    cmap = plt.get_cmap("tab10" if len(runs) <= 10 else "tab20")
    sizes = {}
    for k, sub in enumerate(runs):
        sub_config = sub.config()
        ev = sub.evaluations(sub_config)
        mask = pareto_mask_of(ev)
        sizes[sub_config.seed] = int(mask.sum())
        front = ev.objectives[mask]
        order = np.argsort(front[:, 0])
        j = 1 if front.shape[1] > 1 else 0
        ax.plot(front[order, 0], front[order, j], "o-", color=cmap(k % cmap.N), ms=4, label=f"seed {sub_config.seed}")
    ax.set_xlabel(objective_label(config.objective_names[0]))
    ax.set_ylabel(objective_label(config.objective_names[min(1, len(config.objective_names) - 1)]))
    mean = float(np.mean(list(sizes.values())))
    ax.set_title(f"{config.task}: Pareto fronts of {len(runs)} runs (mean size {mean:.1f})")
    ax.legend(loc="best", fontsize="small")
    fig.tight_layout()
    save_figure(fig, run.path / "pareto_runs.png")
    plt.close(fig)
    write_text(run.path / "repeats.yaml", yaml.safe_dump({"pareto_sizes": sizes, "mean_pareto_size": mean}, sort_keys=False))
    return f"{len(runs)} runs, mean Pareto front size {mean:.1f} (per seed: {sizes}); plot {run.path / 'pareto_runs.png'}"
