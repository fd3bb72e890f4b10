"""The robust protocol's numbers of an experiment's report: the races, the episodes each
repetition spent, and the confirmation of the picks beside the operators' sets in many worlds.
Each takes the finished repetitions (``mjxskill.experiment.stats.Repetition``)."""

from __future__ import annotations

import numpy as np

from mjxskill.runs.run_dir import RunConfig


def race_summary(reps: list) -> list[dict]:
    """Per raced repetition: the contenders, each round's size and worlds, the episodes spent,
    the winner and its success over its race worlds."""
    out = []
    for r in reps:
        if r.race is None:
            continue
        won, worlds = r.race.race_success(r.race.winner) if r.race.winner is not None else (0, 0)
        out.append({"seed": r.seed, "contenders": len(r.race.contenders), "episodes": r.race.episodes,
                    "rounds": [{"contenders": len(x.rows), "worlds": x.worlds} for x in r.race.rounds],
                    "winner": r.race.winner, "winner_successes": won, "winner_worlds": worlds})
    return out


def episode_summary(reps: list, config: RunConfig) -> list[dict]:
    """Per repetition of a robust run, the episodes its optimizer run and its pick spent: new
    parameter sets, sets rolled out again, the race; and their total over the paper's
    budget x worlds."""
    out = []
    for r in reps:
        ev = r.optimizer
        fresh = int(np.sum(ev.replaces < 0)) * config.worlds if ev.pooled else len(ev) * config.worlds
        again = int(np.sum(ev.replaces >= 0)) * config.worlds if ev.pooled else 0
        race = r.race.episodes if r.race is not None else 0
        total = fresh + again + race
        out.append({"seed": r.seed, "training": fresh, "replication": again, "race": race, "total": total,
                    "of_paper_budget": total / (config.budget * config.worlds)})
    return out


def confirmation_summary(reps: list, per_config: int, episode_seconds: float) -> dict:
    """The pick and the operators' sets in the confirmation worlds: per repetition and candidate
    the known and unseen success and the mean time to success with a failure counted as the
    whole episode; pooled over the repetitions (each repetition has as many worlds)."""
    per_rep = []
    for r in reps:
        c = r.confirmation
        if c is None:
            continue
        entry = {"seed": r.seed, "candidates": {}}
        for k, name in enumerate(c.candidates.names):
            times = None if c.world_seconds is None else np.where(np.isfinite(c.world_seconds[k]), c.world_seconds[k],
                                                                   episode_seconds)
            entry["candidates"][name] = {"known": float(c.success[k, c.known].mean()),
                                         "unseen": _finite(c.success[k, ~c.known].mean()) if (~c.known).any() else None,
                                         "full_episode_time_s": None if times is None else float(times.mean()),
                                         "peak_commanded_force_N": None if c.peak_commanded_force is None
                                         else _finite(c.peak_commanded_force[k])}
        per_rep.append(entry)
    names = list(dict.fromkeys(n for e in per_rep for n in e["candidates"]))
    pooled = {}
    for name in names:
        rows = [e["candidates"][name] for e in per_rep if name in e["candidates"]]
        pooled[name] = {side: _mean_of([row[side] for row in rows]) for side in
                        ("known", "unseen", "full_episode_time_s", "peak_commanded_force_N")}
        unseen = [row["unseen"] for row in rows if row["unseen"] is not None]
        pooled[name]["lowest_unseen"] = min(unseen) if unseen else None
        pooled[name]["repetitions"] = len(rows)
    n_cfg = (len(reps[0].confirmation.known) if reps and reps[0].confirmation is not None else 0)
    return {"per_config": per_config, "configs": n_cfg, "repetitions": per_rep, "pooled": pooled}


def _mean_of(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _finite(v) -> float | None:
    return float(v) if v is not None and np.isfinite(v) else None


__all__ = ["confirmation_summary", "episode_summary", "race_summary"]
