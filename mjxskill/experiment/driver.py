"""Running an experiment: repetition after repetition, each finished and reported before the next.

Per repetition (seed s = seed + i): train the optimizer run ``optimizer/seed-<s>``, train the
random search ``random_search/seed-<s>`` (``mjxskill.training.loop.train``: each batch on disk
before the next, resumed where it stopped), evaluate the optimizer run
(``mjxskill.evaluation.evaluate_run``, worlds drawn from s, chunk by chunk on disk), validate the
solutions in contention for its pick (``mjxskill.evaluation.validation``), then rewrite the report
over every finished repetition. A killed experiment continues where it stopped: a
finished run only replays its file, a current evaluation is reused. Wall times go to
``state.json`` as they are spent (a session's time is written even when it is interrupted).
"""

from __future__ import annotations

import time
from typing import Callable

from mjxskill.evaluation.evaluate_run import evaluate_run
from mjxskill.experiment.directory import (
    Experiment,
    Protocol,
    repetition_settings,
    repetition_validation,
    time_key,
)
from mjxskill.experiment.report import write_report
from mjxskill.training.loop import BatchResult, rollout_evaluator, train
from mjxskill.training.report import write_repeats, write_run_figures
from mjxskill.runs.run_dir import Run, RunConfig
from mjxskill.runs.layout import KINDS
from mjxskill.evaluation.validation import in_contention, validate


def _timed(evaluate, clock: dict) -> Callable[[object, int], BatchResult]:
    """``evaluate`` that adds its seconds and rows to ``clock`` (the physics' share of a run)."""

    def wrapped(params, iteration):
        t0 = time.monotonic()
        result = evaluate(params, iteration)
        clock["simulation"] += time.monotonic() - t0
        clock["rows"] += len(params)
        return result

    return wrapped


def train_timed(exp: Experiment, run: Run, rollout, progress_for) -> None:
    """Trains (or finishes) one run, adding its wall and simulation time to the state."""
    config = run.config()
    key = time_key(KINDS[config.optimizer], config.seed)
    clock = {"simulation": 0.0, "rows": 0}
    t0 = time.monotonic()
    try:
        with run.lock():
            evaluate = _timed(rollout_evaluator(rollout, config.batch_size, config.seed), clock)
            ev = train(run, config, evaluate, progress=progress_for(config))
            write_run_figures(run, config, ev)
    finally:
        if clock["rows"]:
            exp.add_time(key, "train_seconds", time.monotonic() - t0, clock["rows"])
            exp.add_time(key, "simulation_seconds", clock["simulation"], clock["rows"])


def evaluate_timed(exp: Experiment, run: Run, rollout, task, settings: dict, progress=None) -> bool:
    """Evaluates one optimizer run (reused when current); True when it ran now."""
    config = run.config()
    t0 = time.monotonic()
    with run.lock():
        _, _, reused = evaluate_run(run, config, rollout, task, settings, progress=progress)
    if not reused:
        exp.add_time(time_key(KINDS[config.optimizer], config.seed), "evaluate_seconds", time.monotonic() - t0)
    return not reused


def validate_timed(exp: Experiment, run: Run, rollout, config: RunConfig, protocol: Protocol, seed: int) -> bool | None:
    """Validates the pick of one evaluated optimizer run (``mjxskill.evaluation.validation``; reused
    when current). True when it ran now, False when reused, None when the protocol has none."""
    settings = repetition_validation(config, protocol, seed)
    if settings is None:
        return None
    run_config = run.config()
    t0 = time.monotonic()
    with run.lock():
        front = run.front(run_config)
        rows = in_contention(front, protocol.max_force, protocol.validation_candidates)
        _, reused = validate(run, front, rows, rollout, settings)
    if not reused:
        exp.add_time(time_key(KINDS[run_config.optimizer], run_config.seed), "validate_seconds", time.monotonic() - t0)
    return not reused


def run_experiment(exp: Experiment, rollout, task, *, progress_for, log: Callable[[str], None],
                   evaluation_progress=None) -> None:
    """Runs (or continues) every repetition of ``exp`` to its end and writes the report after
    each. ``progress_for(config)``: the training loop's progress reporter for a run;
    ``log(text)``: a line for the user; ``evaluation_progress(done, total)`` per chunk."""
    config, protocol = exp.config(), exp.protocol()
    pairs = exp.runs(config)
    for i, (opt, rnd) in enumerate(pairs):
        seed = config.seed + i
        log(f"repetition {i + 1} of {len(pairs)} (seed {seed}): optimizer")
        train_timed(exp, opt, rollout, progress_for)
        log(f"repetition {i + 1} of {len(pairs)} (seed {seed}): random search")
        train_timed(exp, rnd, rollout, progress_for)
        log(f"repetition {i + 1} of {len(pairs)} (seed {seed}): evaluation")
        evaluate_timed(exp, opt, rollout, task, repetition_settings(config, protocol, seed), evaluation_progress)
        if protocol.validation_per_config:
            log(f"repetition {i + 1} of {len(pairs)} (seed {seed}): validation of the pick")
            validate_timed(exp, opt, rollout, config, protocol, seed)
        log(write_report(exp))
    for repeated in (exp.optimizer, exp.random_search):
        if config.repeats > 1:
            log(write_repeats(repeated, repeated.config(), [p for p in repeated.sub_runs(repeated.config())]))


__all__ = ["evaluate_timed", "run_experiment", "train_timed", "validate_timed"]
