"""The learned Pareto solutions of a run against baselines (``python -m mjxskill.evaluate``).

Candidates: every Pareto solution of the run (``pareto-<k>``, k = row of pareto.csv), the
planner-only parameters (the skill defaults), ``--random`` uniform parameter sets, and the
manual parameter sets of the scenario (operators' choices). Each runs ``--per-config`` worlds
from every start configuration: the known ones (training) and the unseen ones (evaluation
only), the same explicit worlds for every candidate, ``batch_size`` candidates per call.

Per candidate and start configuration: the success rate, the mean final position error, the
measured contact force of the tool (peak and mean) and the mean time until the tree returned
SUCCESS over the successful worlds; per candidate the largest COMMANDED force,
``peak_commanded_force`` (mean over its worlds). Box plots like the paper's (``box_plot``: one sample per
candidate and start configuration, two-sided Mann-Whitney U against a reference group with the
paper's stars: * p < 0.1, ** p < 0.05, *** p < 0.01, **** p < 0.001, ns otherwise). The files
of a run's evaluation: ``mjxskill.evaluation.evaluate_run``.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO, NamedTuple, Sequence

import numpy as np

from mjxskill._headless import pyplot
from mjxskill.runs.atomic_write import replace_whole, save_figure

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.protocol import Rollout
    from mjxskill.task import PlannedTask


GROUPS = ("pareto", "planner", "random", "manual")
# The operators' sets are the scenario's manual_parameters: examples invented for this repository
# (the paper's operators' sets are unpublished), and every table and plot says so.
GROUP_LABELS = {"pareto": "Pareto (learned)", "planner": "planner only", "random": "random",
                "manual": "operators (illustrative)"}


class Candidates(NamedTuple):
    """names (N,), groups (N,) one of GROUPS, params (N, P)."""

    names: tuple[str, ...]
    groups: tuple[str, ...]
    params: np.ndarray


# Per-world metrics the evaluation averages per candidate and start configuration (N, C).
METRICS = ("position_error", "peak_contact_force", "mean_contact_force")


class Evaluation(NamedTuple):
    """success (N, C) success rate of each candidate from each start configuration; known (C,)
    bool: a training configuration (else unseen); config_names (C,); position_error (N, C)
    mean final position error of the task's object, m (how close a failure came);
    peak_contact_force, mean_contact_force (N, C): the measured contact force of the tool, N,
    its peak and mean in an episode, averaged over the worlds (NaN where a world diverged);
    peak_commanded_force (N,) the largest force the skills COMMANDED in an episode, N, mean over
    the candidate's worlds (what an operator sets; the experiment's pick bounds it);
    success_seconds (N, C) mean time until the tree returned SUCCESS over the successful worlds
    of each configuration, s (NaN where none succeeded); world_seconds (N, C, W) that time in
    each of the W worlds of a configuration, NaN where the world failed or the tree did not
    return SUCCESS (what the paired and full-episode times need; None in an evaluation written
    before it was kept). The metrics are None when the rollout does not report them."""

    candidates: Candidates
    success: np.ndarray
    known: np.ndarray
    config_names: tuple[str, ...]
    position_error: np.ndarray | None = None
    peak_contact_force: np.ndarray | None = None
    mean_contact_force: np.ndarray | None = None
    peak_commanded_force: np.ndarray | None = None
    success_seconds: np.ndarray | None = None
    world_seconds: np.ndarray | None = None

    def mean(self, known: bool) -> np.ndarray:
        """(N,) mean success over the known (or the unseen) configurations."""
        cols = self.known if known else ~self.known
        return self.success[:, cols].mean(axis=1) if cols.any() else np.full(len(self.success), np.nan)


def build_candidates(task: PlannedTask, pareto_params: np.ndarray, n_random: int, seed: int) -> Candidates:
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


# What one chunk of an evaluation keeps (when the rollout reports it): success and METRICS per
# configuration (b, C), the commanded force per candidate (b,), the time to success (b, C) and
# per world (b, C, W).
CHUNK_FIELDS = ("success", *METRICS, "peak_commanded_force", "success_seconds", "world_seconds")


EVALUATION_STREAM = 0xE7A1  # the evaluation worlds' PRNG stream (training 0x0ED0)


def evaluation_worlds(rollout: Rollout, per_config: int, seed: int, stream: int = EVALUATION_STREAM):
    """The worlds every candidate runs in: ``per_config`` from each known, then each unseen
    start configuration (configuration-major, leading shape (C * per_config,)), drawn from
    ``seed``'s ``stream``. Returns (worlds, config_names (C,), known (C,) bool)."""
    import jax  # lazy: ~1 s; evaluate's --help and bad-input errors import this module

    scn = rollout.scenario
    known_cfg, unseen_cfg = np.asarray(scn.robot.start_configs), np.asarray(scn.robot.eval_configs)
    key_known, key_unseen = jax.random.split(jax.random.fold_in(jax.random.PRNGKey(seed), stream))
    parts = [rollout.worlds_per_config(key_known, per_config, known_cfg)]
    if len(unseen_cfg):
        parts.append(rollout.worlds_per_config(key_unseen, per_config, unseen_cfg))
    worlds = jax.tree.map(lambda *xs: np.concatenate([np.asarray(x) for x in xs]), *parts)
    names = tuple([f"known-{i}" for i in range(len(known_cfg))] + [f"unseen-{j}" for j in range(len(unseen_cfg))])
    known = np.array([True] * len(known_cfg) + [False] * len(unseen_cfg))
    return worlds, names, known


def evaluate_chunk(rollout: Rollout, chunk: np.ndarray, worlds, n_cfg: int, per_config: int, batch_size: int) -> dict:
    """One call: ``chunk`` (b <= batch_size, P) padded to ``batch_size`` (one compiled shape),
    in ``worlds``. Returns CHUNK_FIELDS -> arrays of b rows (a field the rollout lacks: absent)."""
    padded = np.concatenate([chunk, np.repeat(chunk[:1], batch_size - len(chunk), axis=0)])
    out = rollout.run_worlds(padded, worlds)
    b = len(chunk)
    per = lambda a: np.asarray(a, np.float64)[:b].reshape(b, n_cfg, per_config)  # noqa: E731
    success = per(out.success)
    result = {"success": success.mean(axis=2)}
    metrics = getattr(out, "metrics", None) or {}
    for name in METRICS:  # per configuration: (b, C)
        if name in metrics:
            result[name] = per(metrics[name]).mean(axis=2)
    if "peak_commanded_force" in metrics:  # per candidate, over all its worlds: (b,)
        result["peak_commanded_force"] = per(metrics["peak_commanded_force"]).reshape(b, -1).mean(axis=1)
    if "bt_done_tick" in metrics:
        # the tick the root returned SUCCESS ends that tick: (tick + 1) / bt_hz seconds in
        ticks = per(metrics["bt_done_tick"])
        done = (success > 0) & (ticks >= 0)
        seconds = np.where(done, (ticks + 1) / float(rollout.scenario.bt_hz), 0.0)
        count = done.sum(axis=2)
        with np.errstate(invalid="ignore", divide="ignore"):
            result["success_seconds"] = np.where(count > 0, seconds.sum(axis=2) / np.maximum(count, 1), np.nan)
        result["world_seconds"] = np.where(done, seconds, np.nan)
    return result


def evaluate_candidates(rollout: Rollout, candidates: Candidates, per_config: int, seed: int, batch_size: int,
                        done: dict | None = None, on_chunk=None, stream: int = EVALUATION_STREAM) -> Evaluation:
    """Runs every candidate in the same per-configuration worlds (known + unseen configs, from
    ``seed``'s ``stream``), in chunks of ``batch_size`` candidates. ``done``: chunk start -> a
    chunk's results computed before (skipped: an evaluation resumes); ``on_chunk(start,
    result)`` is called after each new chunk (to keep it on disk)."""
    worlds, names, known = evaluation_worlds(rollout, per_config, seed, stream)
    n_cfg = len(names)
    params = candidates.params
    chunks = []
    for start in range(0, len(params), batch_size):
        result = (done or {}).get(start)
        if result is None:
            result = evaluate_chunk(rollout, params[start : start + batch_size], worlds, n_cfg, per_config, batch_size)
            if on_chunk is not None:
                on_chunk(start, result)
        chunks.append(result)
    joined = {f: np.concatenate([c[f] for c in chunks]) if chunks and all(f in c for c in chunks) else None
              for f in CHUNK_FIELDS}
    if joined["success"] is None:
        joined["success"] = np.zeros((0, n_cfg))
    # success: set above
    return Evaluation(candidates, joined.pop("success"), known, names, **joined)  # type: ignore[arg-type]


# The paper's significance levels (its Fig. 4): one more star for each level the p-value is under.
STAR_LEVELS = (0.1, 0.05, 0.01, 0.001)


def stars_of(p: float) -> str:
    n = sum(p < level for level in STAR_LEVELS)
    return "*" * n if n else "ns"


EXACT_MAX_SAMPLES = 50  # both samples together: the exact null distribution up to this size


def significance(a: np.ndarray, b: np.ndarray) -> tuple[float, str]:
    """Two-sided Mann-Whitney U p-value of samples a vs b and its stars (``STAR_LEVELS``): from
    the exact distribution of U where it holds, small samples without ties (ten hypervolumes a
    side: the normal approximation said 1.8e-4 where two fronts that separate completely have
    2 / C(20, 10) = 1.1e-5), else the normal approximation with the tie correction (success
    rates over a few worlds tie a lot)."""
    from scipy.stats import mannwhitneyu  # lazy: scipy.stats ~0.7 s, as jax in evaluation_worlds

    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if len(a) == 0 or len(b) == 0 or (np.all(a == a[0]) and np.all(b == a[0])):
        return 1.0, "ns"  # identical samples: no evidence of a difference
    both = np.concatenate([a, b])
    exact = len(both) <= EXACT_MAX_SAMPLES and len(np.unique(both)) == len(both)
    p = float(mannwhitneyu(a, b, alternative="two-sided", method="exact" if exact else "asymptotic").pvalue)
    return p, stars_of(p)


def group_samples(ev: Evaluation, group: str, known: bool) -> np.ndarray:
    """Success rates of ``group``: one sample per (candidate, start configuration)."""
    rows = np.array([g == group for g in ev.candidates.groups])
    cols = ev.known if known else ~ev.known
    return ev.success[np.ix_(rows, cols)].ravel()


def box_plot(samples: dict, reference: str, path: Path, title: str, *, root: Path | None = None) -> dict:
    """Box plots of ``samples`` (label -> (known samples, unseen samples)), known and unseen
    panels side by side, each group tested against ``reference`` (a label) with its stars above,
    into ``path`` (below ``root``, the run: ``save_figure``); returns the tests
    {(known|unseen, label): (p, stars)}."""
    plt = pyplot()
    labels = list(samples)
    panels = [("known", 0)] + ([("unseen", 1)] if any(len(v[1]) for v in samples.values()) else [])
    fig, axes = plt.subplots(1, len(panels), figsize=(1.1 * len(labels) * len(panels) + 2.5, 4.6), sharey=True, squeeze=False)
    tests = {}
    for ax, (panel, side) in zip(axes[0], panels):
        data = [np.asarray(samples[label][side], np.float64) for label in labels]
        ax.boxplot([d if len(d) else [np.nan] for d in data], showmeans=True)
        ax.set_xticks(range(1, len(labels) + 1), labels, rotation=20, ha="right")
        ax.set_title(f"{panel} start configurations")
        ax.set_ylim(-0.05, 1.25)
        for k, label in enumerate(labels):
            if label == reference or reference not in samples:
                continue
            p, stars = significance(data[labels.index(reference)], data[k])
            tests[(panel, label)] = (p, stars)
            ax.text(k + 1, 1.1, stars, ha="center", fontsize=11)
    axes[0][0].set_ylabel("success rate (fraction of worlds)")
    fig.suptitle(f"{title}  (Mann-Whitney U vs {reference})", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, root=root)
    plt.close(fig)
    return tests


def plot_boxes(ev: Evaluation, path: Path, title: str, *, root: Path | None = None) -> dict:
    """``box_plot`` of one run's groups against the Pareto group; returns the tests
    {(known|unseen, group): (p, stars)}."""
    present = [g for g in GROUPS if g in ev.candidates.groups]
    samples = {GROUP_LABELS[g]: (group_samples(ev, g, True), group_samples(ev, g, False)) for g in present}
    labelled = box_plot(samples, GROUP_LABELS["pareto"], path, title, root=root)
    by_label = {GROUP_LABELS[g]: g for g in present}
    return {(panel, by_label[label]): test for (panel, label), test in labelled.items()}


# evaluation.csv's per-configuration metric columns: (header, Evaluation field, unit suffix)
CSV_METRICS = (("position_error", "position_error", "m"), ("peak_contact_force", "peak_contact_force", "N"),
               ("mean_contact_force", "mean_contact_force", "N"))


def write_csv(ev: Evaluation, parameter_names: Sequence[str], path: Path, *, root: Path | None = None) -> None:
    """One row per candidate: parameters, success known/unseen and per configuration, each
    metric's mean over the known and over the unseen configurations' worlds, then (when
    measured) the commanded force (peak_commanded_force_N) and the time to success."""
    present = [(head, getattr(ev, field), unit) for head, field, unit in CSV_METRICS if getattr(ev, field) is not None]
    force, seconds = ev.peak_commanded_force, ev.success_seconds

    def write(out: BinaryIO) -> None:
        fh = io.StringIO(newline="")  # the rows as text, then written whole
        writer = csv.writer(fh)
        writer.writerow(["candidate", "group", *parameter_names, "success_known", "success_unseen",
                         *(f"success_{c}" for c in ev.config_names)]
                        + [f"{head}_{side}_{unit}" for head, _, unit in present for side in ("known", "unseen")]
                        + ([] if force is None else ["peak_commanded_force_N"])
                        + ([] if seconds is None else ["success_time_s"]))
        known, unseen = ev.mean(True), ev.mean(False)
        for i, name in enumerate(ev.candidates.names):
            extra = [repr(float(values[i, cols].mean())) if cols.any() else "nan"
                     for _, values, _ in present for cols in (ev.known, ~ev.known)]
            extra += [] if force is None else [repr(float(force[i]))]
            extra += [] if seconds is None else [repr(mean_success_seconds(ev, [i]))]
            writer.writerow([name, ev.candidates.groups[i], *map(repr, map(float, ev.candidates.params[i])),
                             repr(float(known[i])), repr(float(unseen[i])), *map(repr, map(float, ev.success[i]))] + extra)
        out.write(fh.getvalue().encode())

    replace_whole(Path(path), write, root=root)


def mean_success_seconds(ev: Evaluation, rows, cols=None) -> float:
    """Mean time to success over every successful world of candidates ``rows`` (configurations
    ``cols``, default all): each configuration's mean weighted by its successes. NaN: none."""
    if ev.success_seconds is None:
        return float("nan")
    cols = np.ones(len(ev.config_names), bool) if cols is None else cols
    rate, seconds = ev.success[np.ix_(rows, cols)], ev.success_seconds[np.ix_(rows, cols)]
    weight = np.where(np.isfinite(seconds), rate, 0.0)
    return float(np.sum(np.where(weight > 0, seconds, 0.0) * weight) / weight.sum()) if weight.sum() > 0 else float("nan")


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
    if ev.peak_contact_force is not None:  # the measured contact force of the tool, over all configurations
        head.append("contact F peak [N]")
        for i, row in enumerate(rows):
            row.append(f"{ev.peak_contact_force[i].mean():.1f}")
    widths = [max(len(r[c]) for r in [head, *rows]) for c in range(len(head))]
    fmt = lambda r: "  ".join(x.ljust(w) if c < 2 else x.rjust(w) for c, (x, w) in enumerate(zip(r, widths)))  # noqa: E731
    lines = [fmt(head), *map(fmt, rows), "", f"{'group':<24} known  unseen  (mean success; Mann-Whitney U vs Pareto)"]
    for g in GROUPS:
        if g not in ev.candidates.groups:
            continue
        k, u = group_samples(ev, g, True), group_samples(ev, g, False)
        note = "" if g == "pareto" else "  " + ", ".join(
            f"{lab} p={tests[(lab, g)][0]:.3g} {tests[(lab, g)][1]}" for lab in ("known", "unseen") if (lab, g) in tests)
        lines.append(f"{GROUP_LABELS[g]:<24} {k.mean():>5.0%}  {u.mean() if len(u) else float('nan'):>6.0%}{note}")
    return "\n".join(lines)
