"""The evaluation of one run on disk, written as it goes and resumed (``evaluate``, ``experiment``).

``RUN_DIR/evaluation/``::

    evaluation.json   the whole evaluation as plain data (its settings, the candidates, success,
                      position error, measured contact force (peak, mean) and time to success
                      per start configuration, the time to success per world (world_seconds,
                      null where a world did not succeed), the commanded force
                      peak_commanded_force per candidate; NaN as null): what the pooled
                      evaluations and the reports read
    evaluation.csv    one row per candidate (``mjxskill.evaluation.baselines.write_csv``)
    success.png       box plots of the groups, Mann-Whitney U against the Pareto group
    chunks.jsonl      while it runs: each finished chunk of candidates, one JSON line, flushed
                      and fsynced; a killed evaluation continues from it; removed once
                      evaluation.json is in place

An evaluation is *current* when ``evaluation.json`` has the same settings (worlds per
configuration, random sets, seed, engine, episode length) and the same Pareto solutions as the
run has now; a current evaluation is reused, not run again (the same inputs give the same
numbers). One with other settings is replaced only when the caller allows it
(``differences_from_earlier``: ``evaluate`` refuses without ``--replace``). A chunk line is used only when its settings and parameter sets are the ones asked
for; a line cut short by a kill is evaluated again. Format 2 (the commanded force named
peak_commanded_force, the contact forces added): an evaluation or chunk of format 1 (its
max_force) is not used, the run is evaluated again.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mjxskill._files import is_regular
from mjxskill.errors import RunError
from mjxskill.runs.bounds import call_episodes_problem
from mjxskill.scenario.fields import read_text
from mjxskill.runs.atomic_write import append_text, check_folder, make_folder, read_below, remove_file, write_json
from mjxskill.evaluation.baselines import (
    CHUNK_FIELDS,
    Candidates,
    Evaluation,
    build_candidates,
    evaluate_candidates,
    plot_boxes,
    write_csv,
)
from mjxskill.runs.run_dir import Run, RunConfig

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.protocol import Rollout
    from mjxskill.task import PlannedTask

FOLDER = "evaluation"
RESULT = "evaluation.json"
CHUNKS = "chunks.jsonl"
FORMAT = "mjxskill.evaluation/2"
PER_CANDIDATE = ("peak_commanded_force",)  # (N,)
PER_WORLD = ("world_seconds",)  # (N, C, W); the other CHUNK_FIELDS are (N, C)


def _shape(field: str, n: int, n_cfg: int) -> tuple[int, ...]:
    return (n,) if field in PER_CANDIDATE else (n, n_cfg, -1) if field in PER_WORLD else (n, n_cfg)


def evaluation_settings(per_config: int, n_random: int, seed: int, batch_size: int, engine: str,
                        episode_seconds: float) -> dict:
    """What an evaluation's numbers depend on besides the run (batch_size: how many candidates
    share a call; it only groups the work)."""
    return {"per_config": int(per_config), "random": int(n_random), "seed": int(seed), "batch_size": int(batch_size),
            "engine": str(engine), "episode_seconds": float(episode_seconds)}


def call_problem(settings: dict, scn) -> str | None:
    """Why an evaluation with ``settings`` of a run of ``scn`` cannot run here (None: it can):
    a call holds ``batch_size`` candidates x ``per_config`` worlds x every start configuration
    (known and unseen) at once, bounded as every command's call (``mjxskill.runs.bounds``)."""
    configs = len(scn.robot.start_configs) + len(scn.robot.eval_configs)
    episodes = settings["batch_size"] * settings["per_config"] * configs
    return call_episodes_problem(episodes, f"--batch-size {settings['batch_size']} x --per-config {settings['per_config']} "
                                           f"x {configs} start configurations")


RESULT_SETTINGS = ("per_config", "random", "seed", "engine", "episode_seconds")  # what the numbers depend on


def _same(a: dict, b: dict) -> bool:
    return all(a.get(k) == b.get(k) for k in RESULT_SETTINGS)


def differences_from_earlier(run: Run, settings: dict) -> list[tuple[str, object, object]]:
    """``(setting, the earlier value, the asked value)`` for each setting in which the run's
    complete evaluation differs from ``settings``: an evaluation with these settings would
    replace it. Empty when the run has none (or a damaged one, which is evaluated again)."""
    try:
        _, own = load_evaluation(run)
    except RunError:
        return []
    return [(k, own.get(k), settings.get(k)) for k in RESULT_SETTINGS if own.get(k) != settings.get(k)]


def evaluation_current(run: Run, config: RunConfig, settings: dict) -> bool:
    """Whether ``run`` has an evaluation with ``settings`` of the Pareto front it has now (a
    missing or damaged one is not)."""
    try:
        ev, own = load_evaluation(run)
        front = run.front(config)
    except RunError:
        return False
    pareto = [i for i, g in enumerate(ev.candidates.groups) if g == "pareto"]
    return _same(own, settings) and np.array_equal(ev.candidates.params[pareto], front.params)


def evaluate_run(run: Run, config: RunConfig, rollout: Rollout, task: PlannedTask, settings: dict, progress=None) -> tuple[Evaluation, dict, bool]:
    """Evaluates ``run``'s Pareto front against the baselines with ``rollout`` (either engine)
    and writes ``RUN_DIR/evaluation/``; reuses a current evaluation. ``progress(done, total)``
    after each chunk. Returns (evaluation, tests of the box plot, whether it was reused)."""
    problem = call_problem(settings, rollout.scenario)
    if problem is not None:  # before anything is written
        raise RunError(problem)
    front = run.front(config)
    candidates = build_candidates(task, front.params, settings["random"], settings["seed"])
    folder = run.path / FOLDER
    check_folder(run.path, folder)  # never read or written through a link below the run
    if is_regular(folder / RESULT, RunError):
        try:
            old, old_settings = load_evaluation(run)
        except RunError:
            old = None  # damaged: evaluated again below, the chunks kept so far are still used
        if old is not None and _same(old_settings, settings) and _same_candidates(old.candidates, candidates):
            remove_file(folder / CHUNKS, root=run.path)  # left by a run killed as it finished: the evaluation is whole
            write_csv(old, config.parameter_names, folder / "evaluation.csv", root=run.path)  # derived: rewritten, never missing
            return old, plot_boxes(old, folder / "success.png", _title(config), root=run.path), True
    make_folder(run.path, folder)  # never through a link below the run
    chunk_path = folder / CHUNKS
    done = _read_chunks(run.path, chunk_path, settings, candidates)

    def keep(start: int, result: dict) -> None:
        line = {"format": FORMAT, "settings": settings, "start": start,
                "params": candidates.params[start : start + len(result["success"])].tolist(),
                **{k: _plain(v) for k, v in result.items()}}
        append_text(chunk_path, json.dumps(line) + "\n", root=run.path)
        if progress is not None:
            progress(min(start + len(result["success"]), len(candidates.names)), len(candidates.names))

    ev = evaluate_candidates(rollout, candidates, settings["per_config"], settings["seed"], settings["batch_size"],
                             done=done, on_chunk=keep)
    write_csv(ev, config.parameter_names, folder / "evaluation.csv", root=run.path)
    tests = plot_boxes(ev, folder / "success.png", _title(config), root=run.path)
    # evaluation.json last: its presence says the evaluation is complete
    write_json(folder / RESULT, {"format": FORMAT, "settings": settings, "parameter_names": list(config.parameter_names),
                                  **evaluation_document(ev)}, root=run.path)
    remove_file(chunk_path, root=run.path)
    return ev, tests, False


def _title(config: RunConfig) -> str:
    return f"{config.task}, seed {config.seed}: success rate per start configuration"


def _same_candidates(a: Candidates, b: Candidates) -> bool:
    return a.names == b.names and a.groups == b.groups and np.array_equal(a.params, b.params)


def load_evaluation(run: Run) -> tuple[Evaluation, dict]:
    """(evaluation, its settings) from ``RUN_DIR/evaluation/evaluation.json``; RunError when it
    is missing or damaged."""
    path = run.path / FOLDER / RESULT
    if not is_regular(path, RunError):
        raise RunError(f"{run.path} has not been evaluated yet (no {FOLDER}/{RESULT}): run python -m mjxskill.evaluate {run.path}")
    return read_evaluation(path, FORMAT, "evaluation", "delete it and evaluate again")


def read_evaluation(path: Path, fmt: str, what: str, remedy: str) -> tuple[Evaluation, dict]:
    """(evaluation, its settings) from a file :func:`evaluation_document` wrote with format
    ``fmt``; RunError naming ``what`` and the ``remedy`` when it is damaged."""
    try:
        doc = json.loads(read_text(path, RunError, what))
        if doc.get("format") != fmt:
            raise ValueError(f"format {fmt!r} expected")
        c = doc["candidates"]
        n, n_cfg = len(c["names"]), len(doc["config_names"])
        candidates = Candidates(tuple(c["names"]), tuple(c["groups"]), _array(c["params"], (n, -1)))
        optional = {k: (None if doc.get(k) is None else _array(doc[k], _shape(k, n, n_cfg)))
                    for k in CHUNK_FIELDS if k != "success"}
        ev = Evaluation(candidates, _array(doc["success"], (n, n_cfg)), np.array(doc["known"], bool),
                        tuple(doc["config_names"]), **optional)
        if ev.known.shape != (n_cfg,) or not isinstance(doc["settings"], dict):
            raise ValueError("the configurations do not match")
    except (KeyError, TypeError, ValueError, AttributeError) as err:
        raise RunError(f"{path} is not a readable {what} ({err}); {remedy}") from None
    return ev, doc["settings"]


def _array(values, shape) -> np.ndarray:
    """Nested lists (None: NaN) -> a float64 array of ``shape`` (-1: any length)."""
    a = np.array(_nan(values), np.float64)
    return a.reshape(shape) if a.size else np.zeros(tuple(max(s, 0) for s in shape))


def _nan(values):
    return [_nan(v) for v in values] if isinstance(values, list) else np.nan if values is None else values


def _plain(value):
    """An array -> nested lists with NaN as None (JSON has no NaN)."""
    a = np.asarray(value, np.float64)
    if a.ndim == 0:
        return float(a) if math.isfinite(a) else None
    return [_plain(v) for v in a]


def evaluation_document(ev: Evaluation) -> dict:
    """``ev`` as plain JSON data (NaN as null), what :func:`read_evaluation` reads."""
    c = ev.candidates
    return {"candidates": {"names": list(c.names), "groups": list(c.groups), "params": _plain(c.params)},
            "config_names": list(ev.config_names), "known": [bool(k) for k in ev.known], "success": _plain(ev.success),
            **{k: None if getattr(ev, k) is None else _plain(getattr(ev, k))
               for k in CHUNK_FIELDS if k != "success"}}


def _read_chunks(root: Path, path: Path, settings: dict, candidates: Candidates) -> dict:
    """Chunk start -> results of the usable lines of ``chunks.jsonl`` of the run ``root`` (see
    the module docstring); read only when it is a regular file, never through a link below the run."""
    done: dict[int, dict] = {}
    if not is_regular(path, RunError):
        return done
    for text in read_below(root, path).decode(errors="replace").splitlines():
        try:
            line = json.loads(text)
            start = int(line["start"])
            params = np.array(line["params"], np.float64)
            if line.get("format") != FORMAT or not _same(line["settings"], settings) or line["settings"].get("batch_size") != settings["batch_size"]:
                continue
            if start % settings["batch_size"] or not np.array_equal(params, candidates.params[start : start + len(params)]):
                continue
            n = len(params)
            n_cfg = len(line["success"][0]) if n else 0
            result = {k: _array(line[k], _shape(k, n, n_cfg)) for k in CHUNK_FIELDS if k in line}
            if "success" in result and len(result["success"]) == n:
                done[start] = result
        except (ValueError, KeyError, TypeError, AttributeError):
            continue  # a line cut short by a kill: that chunk is evaluated again
    return done


__all__ = ["CHUNKS", "FOLDER", "RESULT", "RESULT_SETTINGS", "differences_from_earlier", "evaluate_run", "evaluation_current",
           "evaluation_document", "evaluation_settings", "load_evaluation", "read_evaluation"]
