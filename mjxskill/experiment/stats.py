"""The numbers of an experiment's report, over its finished repetitions (plain data: report.json).

A repetition is finished when its optimizer run and its random search reached the budget, the
optimizer run's evaluation has the protocol's settings and, when the protocol validates the
pick, its validation is current (``mjxskill.evaluation.validation``). Hypervolume: both runs of every
finished repetition are measured in one space, the objectives negated (minimized) and scaled
per objective to [0, 1] by the minimum and maximum over every finite evaluation of every one of
those runs; the reference point is 1 + ``HV_MARGIN`` in each objective (the worst value of all
runs plus 10 % of the range, as a run's own reference is made), so the largest possible
hypervolume is 1.1 ** O. Front sizes: the sample standard deviation (ddof 1) over repetitions.
"""

from __future__ import annotations

from dataclasses import asdict
from typing import Any, NamedTuple

import numpy as np

from mjxskill.evaluation.baselines import Evaluation, significance
from mjxskill.evaluation.confirmation import confirmation_candidates, load_confirmation
from mjxskill.evaluation.racing import Race
from mjxskill.experiment.directory import (
    Experiment,
    Protocol,
    is_done,
    repetition_confirmation,
    time_key,
)
from mjxskill.experiment.picks import opt_task, picked_repetition
from mjxskill.experiment.robustness import confirmation_summary, episode_summary, race_summary
from mjxskill.training.front import HV_MARGIN, hypervolume_history, pareto_mask_of
from mjxskill.evaluation.pooled import (
    Pick,
    contenders,
    force_bound,
    full_episode_seconds,
    paired_seconds,
    group_force_and_time,
    group_means,
    pick,
    pooled_samples,
    pooled_tests,
)
from mjxskill.runs.run_dir import Evaluations, RunConfig
from mjxskill.evaluation.validation import Validation

# The paper's numbers (Mayr et al., experiments section), per scenario name.
PAPER = {
    "push": {"front_size": 8.3},
    "peg": {"front_size": 6.1, "picked": 0.96, "manual": 0.522, "random": 0.41, "faster": 0.181, "force_higher": 0.166},
}


class Repetition(NamedTuple):
    """One finished repetition: its seed, both runs' evaluations (training rows), the optimizer's
    training front, its evaluation against the baselines and its pick."""

    seed: int
    optimizer: Evaluations
    random_search: Evaluations
    front: Evaluations
    evaluation: Evaluation
    pick: Pick
    validation: Validation | None = None  # of the pick's contenders (None: the protocol has none)
    training_pick: Pick | None = None  # what the training success alone picks (the rule without validation)
    race: Race | None = None  # the race that made the pick (a run of the robust protocol; None: validated)
    confirmation: Evaluation | None = None  # the pick and the operators' sets in many worlds (None: none)


def finished_repetitions(exp: Experiment, config: RunConfig, protocol: Protocol) -> list[Repetition]:
    """The repetitions whose runs are finished, evaluated, picked (validated or raced, when the
    protocol says so) and confirmed (when it says so), with the settings of ``protocol``."""
    reps, task = [], None
    for i, (opt, rnd) in enumerate(exp.runs(config)):
        rnd_config = rnd.config()
        picked = picked_repetition(exp, config, protocol, i)
        if picked is None or not is_done(rnd, rnd_config):
            continue
        seed, opt_config, front, ev, chosen, validation, raced = picked
        confirmation = None
        settings = repetition_confirmation(config, protocol, seed)
        if settings is not None:
            picked_params = None if chosen.row is None else front.params[chosen.row]
            task = task or opt_task(exp, config)
            confirmation = load_confirmation(opt.path, confirmation_candidates(task, picked_params), settings)
            if confirmation is None:
                continue
        reps.append(Repetition(seed, opt.evaluations(opt_config), rnd.evaluations(rnd_config), front, ev, chosen,
                               validation, pick(front, ev, protocol.max_force, source=protocol.max_force_source), raced,
                               confirmation))
    return reps


def normalization(runs: list[Evaluations]) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) per objective of the negated objectives over every finite row of ``runs``."""
    z = -np.concatenate([r.objectives for r in runs])
    z = np.where(np.isfinite(z), z, np.nan)
    lo, hi = np.nanmin(z, axis=0), np.nanmax(z, axis=0)
    return lo, np.where(hi > lo, hi, lo + 1.0)


def normalized_curve(ev: Evaluations, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(evaluations done after each batch, hypervolume there) in the normalized space."""
    scaled = Evaluations(ev.iteration, ev.params, -((-ev.objectives - lo) / (hi - lo)), *ev[3:])  # not _replace: len() is rows
    return hypervolume_history(scaled, np.full(ev.objectives.shape[1], 1.0 + HV_MARGIN))


def hypervolumes(reps: list[Repetition]) -> dict:
    if not reps:
        return {"optimizer": [], "random_search": []}
    lo, hi = normalization([r.optimizer for r in reps] + [r.random_search for r in reps])
    curves = {kind: [normalized_curve(getattr(r, kind), lo, hi) for r in reps] for kind in ("optimizer", "random_search")}
    finals = {kind: [float(c[1][-1]) for c in curves[kind]] for kind in curves}
    p = significance(np.array(finals["optimizer"]), np.array(finals["random_search"]))[0] if len(reps) > 1 else None
    n_obj = reps[0].optimizer.objectives.shape[1]
    return {
        **finals,
        "reference_point": [1.0 + HV_MARGIN] * n_obj,
        "space": "negated objectives scaled to [0, 1] by the min and max over every evaluation of every run",
        "normalization": {"min": lo.tolist(), "max": hi.tolist()},
        "evaluations": curves["optimizer"][0][0].tolist(),
        "curves": {kind: [c[1].tolist() for c in curves[kind]] for kind in curves},
        "mann_whitney_p_final": p,
    }


def _mean_sd(values) -> dict:
    a = np.asarray(values, np.float64)
    return {"mean": float(a.mean()) if len(a) else None, "sd": float(a.std(ddof=1)) if len(a) > 1 else None}


def front_sizes(reps: list[Repetition]) -> dict:
    opt = [len(r.front) for r in reps]
    rnd = [int(pareto_mask_of(r.random_search).sum()) for r in reps]
    return {**_mean_sd(opt), "per_repetition": {str(r.seed): n for r, n in zip(reps, opt)},
            "random_search": {**_mean_sd(rnd), "per_repetition": {str(r.seed): n for r, n in zip(reps, rnd)}}}


def time_to_success(reps: list[Repetition], episode_seconds: float) -> dict:
    """The picked solutions' time to success against the operators' sets, like with like:
    ``paired`` over the worlds where both succeeded (``pooled.paired_seconds``) and
    ``full_episode`` with a failure counted as the whole episode (``pooled.full_episode_seconds``);
    from the evaluations that kept per-world times (``repetitions``: how many did)."""
    evals, picks = [r.evaluation for r in reps], [r.pick for r in reps]
    a, b, pairs = paired_seconds(evals, picks, "picked", "manual")
    return {"episode_seconds": float(episode_seconds),
            "repetitions": sum(r.evaluation.world_seconds is not None for r in reps),
            "paired": {"picked_s": _finite(a), "operators_s": _finite(b), "paired_worlds": pairs},
            "full_episode": {"picked_s": _finite(full_episode_seconds(evals, picks, "picked", episode_seconds)),
                             "operators_s": _finite(full_episode_seconds(evals, picks, "manual", episode_seconds))}}


def _faster(times: dict) -> float | None:
    """1 - t_picked / t_operators (None: not measured)."""
    a, b = times.get("picked_s"), times.get("operators_s")
    return None if a is None or not b else 1.0 - a / b


def paper_rows(task: str, front: dict, means: dict, force_time: dict, times: dict) -> list[dict]:
    """The side-by-side table: quantity, the paper's value, ours (None: not measured)."""
    paper = PAPER.get(task, {})
    picked_force, _ = force_time.get("picked", (np.nan, np.nan))
    manual_force, _ = force_time.get("manual", (np.nan, np.nan))
    finite = lambda v: float(v) if v is not None and np.isfinite(v) else None  # noqa: E731
    rows = [{"quantity": "Pareto front size (mean over repetitions)", "paper": paper.get("front_size"),
             "ours": front.get("mean"), "unit": "points"}]
    for group, what in (("picked", "success of the best learned (picked) solutions"),
                        ("manual", "success of the operators' sets"), ("random", "success of random parameter sets")):
        m = means.get(group, {})
        rows.append({"quantity": what, "paper": paper.get(group), "ours_known": m.get("known"),
                     "ours_unseen": m.get("unseen"), "unit": "fraction"})
    higher = manual_force / picked_force - 1.0 if picked_force and np.isfinite(picked_force) else np.nan
    paired, full = times["paired"], times["full_episode"]
    # the paper's 18.1 % compares successful insertions: the paired row is its like
    rows.append({"quantity": "learned faster than the operators' sets, on the worlds where both succeed "
                             "(1 - t_picked / t_operators)",
                 "paper": paper.get("faster"), "ours": _faster(paired), "unit": "fraction", "detail": dict(paired)})
    rows.append({"quantity": f"learned faster than the operators' sets, a failure counted as the full "
                             f"{times['episode_seconds']:g} s episode (1 - t_picked / t_operators)",
                 "paper": None, "ours": _faster(full), "unit": "fraction", "detail": dict(full)})
    rows.append({"quantity": "operators' commanded force above the learned (F_operators / F_picked - 1)",
                 "paper": paper.get("force_higher"), "ours": finite(higher), "unit": "fraction",
                 "detail": {"picked_N": finite(picked_force), "operators_N": finite(manual_force)}})
    return rows


def summarize(exp: Experiment) -> dict:
    """Everything report.json holds (see mjxskill.experiment.report)."""
    config, protocol = exp.config(), exp.protocol()
    reps = finished_repetitions(exp, config, protocol)
    evals, picks = [r.evaluation for r in reps], [r.pick for r in reps]
    samples = pooled_samples(evals, picks)
    means = group_means(samples)
    force_time = {g: group_force_and_time(evals, picks, g) for g in samples}
    times = time_to_success(reps, config.episode_seconds)
    front = front_sizes(reps)
    state = exp.state()
    n_known = int(reps[0].evaluation.known.sum()) if reps else None
    robust: dict[str, object] = {}  # only where there is something to say: a paper-protocol report stays as it was
    if any(r.race is not None for r in reps):
        robust["race"] = race_summary(reps)
    if config.protocol == "robust":
        robust["episodes"] = episode_summary(reps, config)
    if any(r.confirmation is not None for r in reps):
        robust["confirmation"] = confirmation_summary(reps, protocol.confirm_per_config, config.episode_seconds)
    return {
        "task": config.task,
        "status": {"repetitions_done": len(reps), "repetitions": config.repeats},
        "protocol": {**{k: v for k, v in asdict(config).items() if k not in ("parameter_names", "parameter_units", "bounds",
                                                                          "objective_names", "optimizer", "scenario",
                                                                          "engine_reason")},
                     "parameters": {n: {"bounds": [lo, hi], "unit": u} for n, lo, hi, u in
                                    zip(config.parameter_names, *config.bounds, config.parameter_units)},
                     "objectives": list(config.objective_names), "scenario": config.scenario,
                     "per_config": protocol.per_config, "random_sets": protocol.random_sets,
                     "max_force": protocol.max_force, "max_force_source": protocol.max_force_source,
                     "validation_per_config": protocol.validation_per_config,
                     "validation_candidates": protocol.validation_candidates,
                     "known_configs": n_known, "unseen_configs": None if not reps else int((~reps[0].evaluation.known).sum()),
                     "evaluation_seeds": "each repetition's own training seed"},
        "pick_rule": pick_rule(protocol, n_known, raced=config.protocol == "robust"),
        "picked": [_picked(r, config) for r in reps],
        "training_pick": training_pick(reps),
        "bound_sweep": bound_sweep(reps, protocol),
        "front_size": front,
        "groups": means,
        "samples": {g: {"known": len(v[0]), "unseen": len(v[1])} for g, v in samples.items()},
        "mann_whitney": pooled_tests(samples),
        "force_and_time": {g: {"peak_commanded_force_N": _finite(f), "success_time_s": _finite(t),
                               "full_episode_time_s": _finite(full_episode_seconds(evals, picks, g, config.episode_seconds))}
                           for g, (f, t) in force_time.items()},
        "time_to_success": times,
        "hypervolume": hypervolumes(reps),
        "wall_time": {str(r.seed): {kind: state["times"].get(time_key(kind, r.seed), {})
                                    for kind in ("optimizer", "random_search")} for r in reps},
        "sessions": state["sessions"],
        "paper": paper_rows(config.task, front, means, force_time, times),
        **robust,
    }


SWEEP_STEPS = 5  # bounds in the sweep: fifths of the largest force on any front (or of the bound, if larger)


def sweep_bounds(bound: float | None, fronts: list[Evaluations]) -> list[float]:
    """The bounds of the report's sweep: ``SWEEP_STEPS`` evenly spaced up to the larger of the
    pick's bound and the largest commanded force on any front (the last one bounds nothing),
    and the pick's bound itself, in N to 0.1 N."""
    forces = np.concatenate([f.peak_commanded_force for f in fronts]) if fronts else np.zeros(0)
    forces = forces[np.isfinite(forces)]
    top = max(bound or 0.0, float(forces.max()) if len(forces) else 0.0)
    grid = {round(top * k / SWEEP_STEPS, 1) for k in range(1, SWEEP_STEPS + 1)} | ({float(bound)} if bound is not None else set())
    return sorted(b for b in grid if b > 0 or top == 0)


def bound_sweep(reps: list[Repetition], protocol: Protocol) -> list[dict]:
    """How the picked success changes with the force bound, from what the experiment has: the
    training fronts, the evaluation (it evaluated every Pareto solution) and the validation. At a
    bound whose contenders the repetition's validation rolled out, the pick is validated as the
    experiment's is; otherwise it is the training success's alone (``validated`` counts the
    former). No rollout is made."""
    out = []
    for bound in sweep_bounds(protocol.max_force, [r.front for r in reps]):
        picks, validated = [], 0
        for r in reps:
            rows = contenders(r.front, bound, protocol.validation_candidates)
            v = r.validation
            if v is not None and set(rows) <= set(v.rows):
                index = [v.rows.index(row) for row in rows]
                sub = Validation(tuple(rows), v.success[index], v.worlds, protocol.validation_candidates,
                                 None if v.seconds is None else v.seconds[index])
                picks.append(pick(r.front, r.evaluation, bound, sub))
                validated += 1
            else:
                picks.append(pick(r.front, r.evaluation, bound))
        means = group_means(pooled_samples([r.evaluation for r in reps], picks)).get("picked", {})
        forces = [float(r.front.peak_commanded_force[p.row]) for r, p in zip(reps, picks) if p.row is not None]
        out.append({"bound_N": bound, "used": protocol.max_force is not None and bound == float(protocol.max_force),
                    "repetitions_with_pick": len(forces), "validated": validated if any(r.validation for r in reps) else None,
                    "known": means.get("known"), "unseen": means.get("unseen"),
                    "mean_commanded_force_N": float(np.mean(forces)) if forces else None})
    return out


def pick_rule(protocol: Protocol, n_known: int | None, raced: bool = False) -> str:
    """The pick rule in words (report.json's ``pick_rule``); ``raced``: the runs' robust protocol
    picks by racing their fronts."""
    force = ("commanded force (peak_commanded_force: the largest feed-forward force the skills command in an episode, "
             "mean over the training worlds; not the measured contact force) is at most the bound")
    source = protocol.max_force_source or force_bound(protocol.max_force)[1]
    bound = "Bound: " + (source if protocol.max_force is None else f"{protocol.max_force:g} N, {source}")
    if raced:
        return (f"the Pareto solutions whose {force} race in fresh worlds of the known start configurations "
                "(successive halving: ceil(log2 K) rounds share the race's episodes, every contender of a round is "
                "rolled out in the same worlds and the better half goes on, ranked by success over all its race "
                "worlds, then the lower mean time to success there with a failure counted as the full episode, "
                "then the higher success bound of training); the last one left is picked. The contenders are the "
                "K with the highest success bound of training among those whose success may be the highest (the "
                "upper bound of their success over their training worlds not below another's lower bound), K the "
                f"most the first round can roll out once in every known start configuration. {bound}")
    if not protocol.validation_per_config:
        return (f"the Pareto solution with the highest training success rate among those whose {force}; ties: the "
                f"higher first objective. {bound}")
    per = protocol.validation_per_config
    worlds = f"{per * n_known} fresh worlds ({per}" if n_known else f"fresh worlds ({per}"
    return (f"of the Pareto solutions whose {force}, the {protocol.validation_candidates} with the highest training "
            f"success rate (ties: the higher first objective) are rolled out again in {worlds} from each known start "
            "configuration, drawn from the repetition's seed apart from the training and evaluation worlds); the one "
            "with the highest success rate there is picked; ties: the lower mean time to success there (a failure "
            "counted as the full episode), then the higher training success rate, then the higher "
            f"first objective. {bound}")


def training_pick(reps: list[Repetition]) -> dict:
    """What the pick would have been without validation: per repetition where it differs, and
    the success rates of those picks pooled (the validation's effect, measured)."""
    if not reps or all(r.validation is None for r in reps):
        return {"validated": False}
    # repetitions() gives every repetition its training pick
    evals, picks = [r.evaluation for r in reps], [r.training_pick for r in reps]
    means = group_means(pooled_samples(evals, picks)).get("picked", {"known": None, "unseen": None})  # type: ignore[arg-type]
    changed = [{"seed": r.seed, "validated_row": r.pick.row, "training_row": r.training_pick.row}  # type: ignore[union-attr]
               for r in reps if r.pick.row != r.training_pick.row]  # type: ignore[union-attr]
    return {"validated": True, "changed": changed, "groups": means}


def _finite(v) -> float | None:
    return float(v) if v is not None and np.isfinite(v) else None


def _picked(r: Repetition, config: RunConfig) -> dict:
    p = r.pick
    out: dict[str, Any] = {"seed": r.seed, "pareto_row": p.row, "bound_N": p.bound, "bound_source": p.source}
    if p.row is not None:
        ev = r.evaluation
        row = ev.candidates.names.index(f"pareto-{p.row}")
        out.update(parameters=dict(zip(config.parameter_names, map(float, r.front.params[p.row]))),
                   training_success=float(r.front.success_rate[p.row]), training_peak_commanded_force_N=float(r.front.peak_commanded_force[p.row]),
                   validation_success=None if r.validation is None else r.validation.success_of(p.row),
                   known=float(ev.mean(True)[row]), unseen=_finite(ev.mean(False)[row]))
    if r.race is not None and p.row is not None:
        won, worlds = r.race.race_success(p.row)
        out.update(race_successes=won, race_worlds=worlds)
        if r.optimizer.pooled:
            # a pooled run's rows have worlds
            out["training_worlds"] = int(r.front.worlds[p.row])  # type: ignore[index]
    if r.confirmation is not None and p.row is not None:
        c = r.confirmation
        out.update(confirmed_known=float(c.success[0, c.known].mean()),
                   confirmed_unseen=_finite(c.success[0, ~c.known].mean()) if (~c.known).any() else None)
    if r.validation is not None:
        out["validation_rates"] = {str(row): rate for row, rate in zip(r.validation.rows, map(float, r.validation.success))}
        out["validation_worlds"] = r.validation.worlds
        if r.validation.seconds is not None:
            out["validation_seconds"] = {str(row): t for row, t in zip(r.validation.rows, map(float, r.validation.seconds))}
    return out


__all__ = ["PAPER", "Repetition", "bound_sweep", "finished_repetitions", "sweep_bounds", "time_to_success", "hypervolumes", "normalization", "normalized_curve", "pick_rule",
           "summarize", "training_pick"]
