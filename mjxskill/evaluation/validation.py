"""The pick's validation: the Pareto solutions in contention rolled out again in fresh worlds.

A Pareto solution's training success rate comes from the few worlds of its own batch
(``--worlds``: 7 in the paper), and the front keeps whatever did best there, so a knife-edge set
that happened to succeed in all of them looks as good as a robust one: on peg an 8 mm spiral
with 100 % training success reached 30-40 % in the evaluation and was picked over a set that
reached 93-100 % at the same training success (docs/experiments/peg). Before the pick
(``mjxskill.evaluation.pooled.pick``) the ``candidates`` Pareto solutions within the force bound
with the highest training success are rolled out in ``per_config`` fresh worlds from each
*known* start configuration, drawn from the evaluation's seed (an experiment's: the
repetition's) on a stream of their own (not the training batches' worlds, not the
evaluation's); the pick takes the highest validation success, and of equal ones the fastest:
the lowest mean time to success over the validation worlds, a failure counted as the full
episode.
An operator could do the same on the real cell before committing to a set; the unseen start
configurations stay unseen until the evaluation.

``RUN_DIR/evaluation/validation.json``: the settings, the validated Pareto rows, their parameters,
success rates and times. It is *current* for a pick when it has the same worlds (per_config, seed,
engine, episode length), validated every row in contention with the same parameters (a
validation of more candidates serves one of fewer) and holds their times (one written before
times were kept is made again); a current one is reused (the same inputs give the same
numbers). It is small and quick to make, so a killed validation is run again
whole. With no solution within the bound there is nothing to validate and no file.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, NamedTuple, Sequence

import numpy as np

from mjxskill._files import is_regular
from mjxskill.engine.common.keys import stream_key
from mjxskill.errors import RunError
from mjxskill.scenario.fields import read_text
from mjxskill.runs.atomic_write import make_folder, write_json
from mjxskill.evaluation.evaluate_run import FOLDER
from mjxskill.evaluation.baselines import evaluate_chunk
from mjxskill.evaluation.pooled import contenders
from mjxskill.runs.run_dir import Evaluations, Run

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.protocol import Rollout

FILE = "validation.json"
FORMAT = "mjxskill.validation/1"
STREAM = 0x7A11D  # the validation worlds' PRNG stream (training: 0x0ED0, evaluation: 0xE7A1)


class Validation(NamedTuple):
    """rows: the validated Pareto rows (the contenders, best in training first); success: their
    success rates (len(rows),) over ``worlds`` validation worlds each; candidates: how many
    contenders were asked for (None: len(rows)); seconds: their mean time to success over those
    worlds, a failure counted as the full episode (what decides between equal success rates;
    None: the rollout reports no times)."""

    rows: tuple[int, ...]
    success: np.ndarray
    worlds: int
    candidates: int | None = None
    seconds: np.ndarray | None = None

    def success_of(self, row: int) -> float:
        return float(self.success[self.rows.index(row)])

    def seconds_of(self, row: int) -> float | None:
        return None if self.seconds is None else float(self.seconds[self.rows.index(row)])


def validation_settings(per_config: int, candidates: int, seed: int, engine: str, episode_seconds: float) -> dict:
    """What a validation's numbers depend on (candidates: how many were asked for)."""
    return {"per_config": int(per_config), "candidates": int(candidates), "seed": int(seed), "engine": str(engine),
            "episode_seconds": float(episode_seconds)}


def _same(a: dict, b: dict) -> bool:
    return all(a.get(k) == b.get(k) for k in ("per_config", "seed", "engine", "episode_seconds"))


def in_contention(front: Evaluations, max_force: float | None, n: int) -> list[int]:
    """The Pareto rows a validated pick chooses from: the ``n`` within the pick's force bound
    ``max_force`` (N of commanded force; None: unbounded) with the best training success."""
    return contenders(front, max_force, n)


def validation_worlds(rollout: Rollout, per_config: int, seed: int):
    """``per_config`` worlds from each known start configuration, from ``seed``'s own stream."""
    known = np.asarray(rollout.scenario.robot.start_configs)
    return rollout.worlds_per_config(stream_key(seed, STREAM), per_config, known), len(known)


def validate_rows(rollout: Rollout, params: np.ndarray, per_config: int, seed: int, pad_to: int = 0,
                  episode_seconds: float | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """(success rate, mean time to success with a failure counted as the ``episode_seconds``
    episode; None when the rollout reports no times) of each row of ``params`` over the
    validation worlds of ``seed``, in one call padded to ``pad_to`` rows (the number of
    candidates asked for: one compiled shape for MJX whatever the number in contention; the
    world count differs from training's and the evaluation's, so MJX compiles that shape once
    more)."""
    if not len(params):
        return np.zeros(0), np.zeros(0)
    worlds, n_cfg = validation_worlds(rollout, per_config, seed)
    out = evaluate_chunk(rollout, params, worlds, n_cfg, per_config, max(len(params), pad_to))
    success = out["success"].mean(axis=1)
    times = out.get("world_seconds")
    if times is None or episode_seconds is None:
        return success, None
    return success, np.where(np.isfinite(times), times, episode_seconds).reshape(len(params), -1).mean(axis=1)


def validate(run: Run, front: Evaluations, rows: Sequence[int], rollout: Rollout, settings: dict) -> tuple[Validation, bool]:
    """Validates Pareto ``rows`` of ``run``'s ``front`` (reuses a current validation.json, else
    rolls them out and writes it). Returns (validation, whether nothing was rolled out)."""
    rows = tuple(int(r) for r in rows)
    old = load_validation(run, front, rows, settings)
    if old is not None:
        return old, True
    success, seconds = validate_rows(rollout, front.params[list(rows)], settings["per_config"], settings["seed"],
                                     settings["candidates"], settings["episode_seconds"])
    n_known = len(rollout.scenario.robot.start_configs)
    result = Validation(rows, success, settings["per_config"] * n_known, settings["candidates"], seconds)
    doc = {"format": FORMAT, "settings": settings, "worlds": result.worlds, "rows": list(rows),
           "params": front.params[list(rows)].tolist(), "success": success.tolist(),
           "seconds": None if seconds is None else seconds.tolist()}
    make_folder(run.path, run.path / FOLDER)  # never through a link below the run
    write_json(run.path / FOLDER / FILE, doc, root=run.path)
    return result, False


def load_validation(run: Run, front: Evaluations, rows: Sequence[int], settings: dict) -> Validation | None:
    """The validation of Pareto ``rows`` on disk when it is current (see the module docstring);
    None when there is none or it is of other worlds or parameters. No rows: an empty
    validation, no file needed. RunError when the file is damaged."""
    if not len(rows):
        return Validation((), np.zeros(0), 0, settings["candidates"], np.zeros(0))
    stored = _read(run)
    if stored is None:
        return None
    doc, stored_rows, worlds, params, success = stored
    if not _same(doc["settings"], settings) or not set(rows) <= set(stored_rows):
        return None
    if "seconds" not in doc:  # written before times were kept: made again (quick), for the pick's tie-break
        return None
    index = [stored_rows.index(r) for r in rows]
    if any(r >= len(front) for r in rows) or not np.array_equal(params[index], front.params[list(rows)]):
        return None
    seconds = None if doc["seconds"] is None else _seconds(doc["seconds"], len(stored_rows), run)[index]
    return Validation(tuple(rows), success[index], worlds, settings["candidates"], seconds)


def _seconds(values, n: int, run: Run) -> np.ndarray:
    try:
        seconds = np.array(values, np.float64).reshape(n)
        if not np.all(np.isfinite(seconds) & (seconds >= 0)):
            raise ValueError("times >= 0 expected")
    except (TypeError, ValueError, OverflowError) as err:
        raise RunError(f"{run.path / FOLDER / FILE} is not a readable validation ({err}); delete it "
                       "(it is made again in a minute)") from None
    return seconds


def validated_success(run: Run, front: Evaluations) -> tuple[np.ndarray, int, np.ndarray] | None:
    """What ``run``'s validation.json says of its current ``front``, whatever its settings (what
    ``select`` shows): (len(front),) success rates, NaN for a row it did not validate or whose
    parameters changed since, its world count, and (len(front),) mean times to success (a
    failure counted as the whole episode; NaN where not validated or not recorded); None when
    the run has no validation. RunError when the file is damaged."""
    stored = _read(run)
    if stored is None:
        return None
    doc, stored_rows, worlds, params, success = stored
    times = doc.get("seconds")
    times = None if times is None else _seconds(times, len(stored_rows), run)
    out, seconds = np.full(len(front), np.nan), np.full(len(front), np.nan)
    for i, r in enumerate(stored_rows):
        if r < len(front) and np.array_equal(params[i], front.params[r]):
            out[r] = success[i]
            if times is not None:
                seconds[r] = times[i]
    return out, worlds, seconds


def validated_union(runs_and_fronts, damaged=None, seconds: list | None = None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """:func:`validated_success` over several (run, front) pairs, the fronts concatenated in
    order (as ``select`` lists them): (their rates, NaN where none; each row's validation world
    count, 0 where none), or (None, None) when no run has a validation. A damaged
    validation.json counts as none and its RunError's message goes to ``damaged`` (None:
    ignored): a listing is still of use without it. ``seconds``, a list if given, gets the rows'
    mean validation times to success appended (NaN where none), for the pick's tie-break."""
    pairs = list(runs_and_fronts)

    def read(run, front):
        try:
            return validated_success(run, front)
        except RunError as err:
            if damaged is not None:
                damaged(str(err))
            return None

    found = [read(run, front) for run, front in pairs]
    if all(v is None for v in found):
        return None, None
    if seconds is not None:
        seconds.extend(np.concatenate([np.full(len(front), np.nan) if v is None else v[2]
                                       for v, (_, front) in zip(found, pairs)]).tolist())
    rates = np.concatenate([np.full(len(front), np.nan) if v is None else v[0] for v, (_, front) in zip(found, pairs)])
    worlds = np.concatenate([np.zeros(len(front), int) if v is None else np.full(len(front), v[1])
                             for v, (_, front) in zip(found, pairs)])
    return rates, np.where(np.isnan(rates), 0, worlds)


def row_validation(rates: np.ndarray | None, worlds: np.ndarray | None, i: int) -> tuple[float, int] | None:
    """(validation success, worlds) of row ``i`` of :func:`validated_union`'s arrays (what an
    export records), or None when that row was not validated."""
    if rates is None or np.isnan(rates[i]):
        return None
    return float(rates[i]), int(worlds[i])  # type: ignore[index]  # validated_union gives both arrays or neither


def _read(run: Run):
    """(document, rows, worlds, params, success) of ``run``'s validation.json, checked; None
    when there is none. RunError when it is damaged."""
    path = run.path / FOLDER / FILE
    if not is_regular(path, RunError):
        return None
    try:
        doc = json.loads(read_text(path, RunError, "validation"))
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise ValueError(f"format {FORMAT!r} expected")
        stored_rows, worlds = doc["rows"], doc["worlds"]
        if not isinstance(stored_rows, list) or not stored_rows or not all(_count(r) for r in stored_rows):
            raise ValueError("rows: a list of Pareto row numbers expected")
        if not _count(worlds) or worlds < 1 or not isinstance(doc["settings"], dict):
            raise ValueError("a positive world count and the settings expected")
        params = np.array(doc["params"], np.float64).reshape(len(stored_rows), -1)
        success = np.array(doc["success"], np.float64).reshape(len(stored_rows))
        if not np.all((success >= 0) & (success <= 1)):
            raise ValueError("success rates in [0, 1] expected")
    except (KeyError, TypeError, ValueError, OverflowError, RecursionError) as err:
        raise RunError(f"{path} is not a readable validation ({err}); delete it (it is made again in a minute)") from None
    return doc, stored_rows, worlds, params, success


def _count(v) -> bool:
    """A JSON integer >= 0 (not a bool, not a float)."""
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


__all__ = ["FILE", "FORMAT", "Validation", "in_contention", "load_validation", "validate", "validate_rows", "validated_success",
           "validated_union", "row_validation", "validation_settings", "validation_worlds"]
