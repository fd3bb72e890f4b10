"""The robust protocol's pick (``mjxskill.runs.training_protocol``): the front raced in fresh worlds.

The contenders are the Pareto solutions within the pick's force bound (commanded force, as
``mjxskill.evaluation.pooled``) whose success may be the highest (their upper bound not below
another's lower bound), best success bound first, as many as the race's first round can roll
out in one world per known start configuration each. The race is successive halving
(Karnin et al. 2013): ceil(log2 K) rounds share its episodes equally; in each round every
contender still in it is rolled out in the same fresh worlds, ``per_config`` from each known
start configuration (common worlds: the contenders are compared on the same offsets and
postures), and the better half goes on, ranked by their success over all their race worlds,
then the lower mean time to success there (a failure counted as the whole episode), then the
higher success bound of training. The last one left is the pick. Only race worlds rank: the
training worlds are the ones the front was selected on, and a set lucky there would carry its
luck into the race.

``RUN_DIR/race.json`` holds the settings, the contenders, their parameters and every finished
round, written whole after each: a race killed mid-round runs that round again (its worlds and
so its results are the same) and one with other settings or another front is run again whole.
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from mjxskill._files import is_regular
from mjxskill.engine.common.keys import stream_key
from mjxskill.errors import RunError
from mjxskill.evaluation.baselines import evaluate_chunk
from mjxskill.runs.atomic_write import write_json
from mjxskill.runs.evaluations_csv import Evaluations
from mjxskill.runs.training_protocol import race_episodes, success_upper_bound
from mjxskill.scenario.fields import read_text

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.protocol import Rollout
    from mjxskill.scenario.schema import Scenario

FILE = "race.json"
FORMAT = "mjxskill.race/1"
STREAM = 0x2ACE  # the race worlds' PRNG stream (training 0x0ED0, evaluation 0xE7A1, validation 0x7A11D)


class Round(NamedTuple):
    """rows: the contenders in the round (rows of the front); per_config: worlds from each known
    start configuration, ``worlds`` in all; successes (len(rows),): worlds succeeded; seconds
    (len(rows),): summed time to success, a failure counted as the whole episode."""

    rows: tuple[int, ...]
    per_config: int
    worlds: int
    successes: np.ndarray
    seconds: np.ndarray


class Race(NamedTuple):
    """contenders: the front rows raced, best success bound first; rounds: the finished rounds;
    winner: the pick (None until the last round is run, or no contender); episodes: spent."""

    contenders: tuple[int, ...]
    rounds: tuple[Round, ...]
    winner: int | None
    episodes: int

    def race_success(self, row: int) -> tuple[int, int]:
        """(worlds succeeded, worlds) of ``row`` over every round it ran in."""
        won = sum(int(r.successes[r.rows.index(row)]) for r in self.rounds if row in r.rows)
        worlds = sum(r.worlds for r in self.rounds if row in r.rows)
        return won, worlds


def race_settings(seed: int, engine: str, episode_seconds: float, episodes: int, max_force: float | None,
                  n_configs: int) -> dict:
    """What a race's numbers depend on besides the front."""
    return {"seed": int(seed), "engine": str(engine), "episode_seconds": float(episode_seconds),
            "episodes": int(episodes), "max_force": None if max_force is None else float(max_force),
            "known_configs": int(n_configs)}


def run_race_settings(config, scenario: Scenario) -> dict:
    """The race settings of a run (its ``RunConfig``) of ``scenario``: its seed, engine and
    episodes, the race's share of its budget (``training_protocol.race_episodes``), the
    scenario's pick bound (``pick.max_force``; none: unbounded)."""
    bound = scenario.pick.max_force if scenario.pick is not None else None
    return race_settings(config.seed, config.engine, config.episode_seconds, race_episodes(config.budget, config.worlds),
                         bound, len(scenario.robot.start_configs))


def describe(race_: Race, front: Evaluations, config, settings: dict) -> str:
    """The race in a few lines: contenders, rounds, the pick and its race success."""
    if race_.winner is None:
        if contenders(front, settings["max_force"]):
            return (f"race: its {settings['episodes']} episodes cannot roll a contender out once from each of the "
                    f"{settings['known_configs']} known start configurations: no pick (a larger budget leaves the race "
                    "more)")
        return "race: no Pareto solution within the pick's force bound, no pick"
    won, worlds = race_.race_success(race_.winner)
    names = [n.split(".")[-1] for n in config.parameter_names]
    values = ", ".join(f"{n} = {v:.4g}" for n, v in zip(names, front.params[race_.winner]))
    rounds = "; ".join(f"{len(r.rows)} x {r.worlds} worlds" for r in race_.rounds)
    return (f"race: {len(race_.contenders)} Pareto solutions in fresh worlds of the known start configurations "
            f"({rounds}; {race_.episodes} episodes)\n"
            f"picked: Pareto row {race_.winner} ({values}), success {won}/{worlds} in its race worlds "
            f"(select it with --pick {race_.winner})")


def contenders(front: Evaluations, max_force: float | None) -> list[int]:
    """The front rows within ``max_force`` (N of commanded force; None: all) that may be the
    most successful, best first: the higher success bound (the last objective of a robust
    run), the higher success rate, the higher first objective. A row whose success upper
    bound over its worlds lies below another's lower bound cannot be the most successful and
    is left out (with pooled rows; a front without world counts keeps every row)."""
    ok = np.ones(len(front), bool) if max_force is None else front.peak_commanded_force <= max_force
    if front.pooled and ok.any():
        upper = success_upper_bound(front.success_rate * front.worlds, front.worlds)
        ok &= upper >= np.max(front.objectives[ok, -1])
    rows = np.flatnonzero(ok)
    order = np.lexsort((-front.objectives[rows, 0], -front.success_rate[rows], -front.objectives[rows, -1]))
    return [int(r) for r in rows[order]]


def schedule(n_contenders: int, n_configs: int, episodes: int) -> tuple[int, list[tuple[int, int]]]:
    """(K, [(contenders in round, worlds per known configuration), ...]): successive halving over
    the first K of ``n_contenders`` with at most ``episodes`` episodes, K the most whose first
    round gets one world per configuration each. No rounds when not even one contender can be
    rolled out once in every configuration."""
    for k in range(n_contenders, 0, -1):
        rounds = max(1, math.ceil(math.log2(k)))
        per_round = episodes // rounds
        if k * n_configs <= per_round:
            plan, alive = [], k
            for _ in range(rounds):
                plan.append((alive, per_round // (alive * n_configs)))
                alive = math.ceil(alive / 2)
            return k, plan
    return 0, []


def race(run_path, front: Evaluations, rollout: Rollout, settings: dict, batch_size: int) -> Race:
    """Races the contenders of ``front`` (reusing the finished rounds of a current race.json,
    writing it after each round) and returns the race. ``batch_size``: the contenders of one
    call (the compiled shape on MJX)."""
    rows = contenders(front, settings["max_force"])
    k, plan = schedule(len(rows), settings["known_configs"], settings["episodes"])
    rows = rows[:k]
    rounds = list(_finished_rounds(run_path, front, rows, settings))
    alive = rows if not rounds else list(_survivors(rounds, front, rounds[-1].rows, len(rounds), plan))
    for index in range(len(rounds), len(plan)):
        per_config = plan[index][1]
        successes, seconds = _roll(rollout, front.params[alive], per_config, settings, index, batch_size)
        rounds.append(Round(tuple(alive), per_config, per_config * settings["known_configs"], successes, seconds))
        _write(run_path, settings, front, rows, rounds)
        alive = _survivors(rounds, front, alive, index + 1, plan)
    winner = int(alive[0]) if rows else None
    if rows:
        _write(run_path, settings, front, rows, rounds, winner)
    return Race(tuple(rows), tuple(rounds), winner, _spent(rounds))


def _spent(rounds) -> int:
    return sum(len(r.rows) * r.worlds for r in rounds)


def _survivors(rounds: list[Round], front: Evaluations, alive, done: int, plan) -> list[int]:
    """The contenders of round ``done`` (the next) ranked on every race world so far, as many as
    it takes (the last round keeps one: the winner)."""
    keep = plan[done][0] if done < len(plan) else 1
    race_of = Race((), tuple(rounds), None, 0)
    totals = {row: race_of.race_success(row) for row in alive}
    seconds = {row: sum(float(r.seconds[r.rows.index(row)]) for r in rounds if row in r.rows) for row in alive}
    order = sorted(alive, key=lambda row: (-totals[row][0] / max(totals[row][1], 1),
                                           seconds[row] / max(totals[row][1], 1), -front.objectives[row, -1], row))
    return order[:keep]


def _roll(rollout: Rollout, params: np.ndarray, per_config: int, settings: dict, index: int, batch_size: int):
    """(worlds succeeded, summed seconds to success with failures as whole episodes) per row of
    ``params``, in round ``index``'s worlds."""
    known = np.asarray(rollout.scenario.robot.start_configs)
    key = stream_key(settings["seed"], STREAM, index)
    worlds = rollout.worlds_per_config(key, per_config, known)
    # MJX compiles one shape: calls of batch_size rows, padded; the native engine takes every
    # contender of the round in one call (padding would roll out copies for nothing)
    size = batch_size if settings["engine"] == "mjx" else len(params)
    successes, seconds = [], []
    for start in range(0, len(params), size):
        chunk = params[start : start + size]
        out = evaluate_chunk(rollout, chunk, worlds, len(known), per_config, size)
        won = out["success"] * per_config  # (b, C) means over per_config worlds -> counts
        successes.append(np.rint(won.sum(axis=1)).astype(int))
        times = out.get("world_seconds")
        full = settings["episode_seconds"]
        seconds.append(np.where(np.isfinite(times), times, full).reshape(len(chunk), -1).sum(axis=1)
                       if times is not None else np.full(len(chunk), full * per_config * len(known)))
    return np.concatenate(successes), np.concatenate(seconds)


def _write(run_path, settings: dict, front: Evaluations, rows, rounds: list[Round], winner: int | None = None) -> None:
    doc = {"format": FORMAT, "settings": settings, "contenders": list(rows), "params": front.params[rows].tolist(),
           "rounds": [{"rows": list(r.rows), "per_config": r.per_config, "successes": r.successes.tolist(),
                       "seconds": r.seconds.tolist()} for r in rounds]}
    if winner is not None:  # the race is over: what select and the reports read
        won = sum(int(r.successes[r.rows.index(winner)]) for r in rounds if winner in r.rows)
        worlds = sum(r.per_config * settings["known_configs"] for r in rounds if winner in r.rows)
        doc.update(winner=int(winner), winner_params=front.params[winner].tolist(), winner_successes=won,
                   winner_worlds=worlds)
    write_json(run_path / FILE, doc)


def raced_pick(run_path, front: Evaluations) -> tuple[int, int, int] | None:
    """(row of ``front``, worlds succeeded, worlds raced) of the finished race on disk whose
    winner is still that row of the front, whatever its settings (what ``select`` shows); None
    when there is none. RunError when the file is damaged."""
    path = run_path / FILE
    if not is_regular(path, RunError):
        return None
    try:
        doc = json.loads(read_text(path, RunError, "race"))
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise ValueError(f"format {FORMAT!r} expected")
        if "winner" not in doc:
            return None
        row, params = int(doc["winner"]), np.array(doc["winner_params"], np.float64)
        won, worlds = int(doc["winner_successes"]), int(doc["winner_worlds"])
    except (KeyError, TypeError, ValueError, OverflowError, RecursionError) as err:
        raise RunError(f"{path} is not a readable race ({err}); delete it (it is run again)") from None
    if not 0 <= row < len(front) or params.shape != front.params[row].shape or not np.array_equal(params, front.params[row]):
        return None
    return row, won, worlds


def _finished_rounds(run_path, front: Evaluations, rows, settings: dict):
    """The rounds of a current race.json (same settings, contenders and parameters); none else."""
    path = run_path / FILE
    if not is_regular(path, RunError):
        return
    try:
        doc = json.loads(read_text(path, RunError, "race"))
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise ValueError(f"format {FORMAT!r} expected")
        if doc["settings"] != settings or doc["contenders"] != list(rows):
            return
        if not np.array_equal(np.array(doc["params"], np.float64).reshape(len(rows), -1), front.params[rows]):
            return
        for r in doc["rounds"]:
            n = len(r["rows"])
            per_config = int(r["per_config"])
            yield Round(tuple(int(v) for v in r["rows"]), per_config, per_config * settings["known_configs"],
                        np.array(r["successes"], int).reshape(n), np.array(r["seconds"], np.float64).reshape(n))
    except (KeyError, TypeError, ValueError, OverflowError, RecursionError) as err:
        raise RunError(f"{path} is not a readable race ({err}); delete it (it is run again)") from None


def load_race(run_path, front: Evaluations, settings: dict) -> Race | None:
    """The finished race of ``front`` on disk with ``settings`` (None: none, or not finished)."""
    rows = contenders(front, settings["max_force"])
    k, plan = schedule(len(rows), settings["known_configs"], settings["episodes"])
    rows = rows[:k]
    rounds = list(_finished_rounds(run_path, front, rows, settings))
    if len(rounds) < len(plan) or not rows:
        return None if rows else Race((), (), None, 0)
    winner = _survivors(rounds, front, list(rounds[-1].rows), len(plan), plan)[0]
    return Race(tuple(rows), tuple(rounds), int(winner), _spent(rounds))


__all__ = ["FILE", "FORMAT", "Race", "Round", "STREAM", "contenders", "describe", "load_race", "race", "race_settings",
           "raced_pick", "run_race_settings", "schedule"]
