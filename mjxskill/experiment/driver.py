"""Running an experiment: repetition after repetition, each finished and reported before the next
(or, on a Ray cluster, several repetitions at the same time: below).

Per repetition (seed s = seed + i): train the optimizer run ``optimizer/seed-<s>``, train the
random search ``random_search/seed-<s>`` (``mjxskill.training.loop.train``: each batch on disk
before the next, resumed where it stopped), evaluate the optimizer run
(``mjxskill.evaluation.evaluate_run``, worlds drawn from s, chunk by chunk on disk), validate the
solutions in contention for its pick (``mjxskill.evaluation.validation``), then rewrite the report
over every finished repetition. A killed experiment continues where it stopped: a
finished run only replays its file, a current evaluation is reused. Wall times go to
``state.json`` as they are spent (a session's time is written even when it is interrupted),
with the wall-clock interval each repetition worked in.

Given several rollouts (``run_experiment(exp, [rollout, ...])``: the experiment command on a Ray
cluster, each rollout on its own share of the cluster's actors), as many repetitions run at the
same time, one thread per rollout taking the next repetition when its own is finished. Each
repetition is still one thread's, which writes its two runs as above (one writer per run
directory, its lock held); the calling thread writes the report after each finished repetition,
in the order they finish. What runs at the same time is the episodes, on the cluster: in this
process the threads take turns (``_Turns``: one lock, released only while a thread waits for its
episodes), because two JAX programs run at once from two threads deadlocked XLA's CPU thread
pool on a 2-core driver (the optimizer's proposals, seen with py-spy), and pyplot, drawing the
figures, keeps global state. The results do not depend on any of it: every episode is
deterministic and every run is seeded by its own seed. Ctrl-C (or a repetition's error) closes
every rollout, which stops their Ray work at once (the batches being run are lost, the finished
ones are on disk, as a sequential run's), and is raised here once the threads have stopped.
"""

from __future__ import annotations

import queue
import threading
import time
from typing import TYPE_CHECKING, Callable, Sequence

from mjxskill.evaluation.evaluate_run import evaluate_run
from mjxskill.evaluation.confirmation import confirm, confirmation_candidates
from mjxskill.evaluation.racing import load_race, race
from mjxskill.experiment.directory import (
    Experiment,
    Protocol,
    repetition_confirmation,
    repetition_race,
    repetition_settings,
    repetition_validation,
    time_key,
)
from mjxskill.experiment.report import write_report
from mjxskill.experiment.picks import repetition_pick
from mjxskill.experiment.stats import finished_repetitions
from mjxskill.training.loop import BatchResult, rollout_evaluator, train
from mjxskill.training.report import write_repeats, write_run_figures
from mjxskill.runs.run_dir import Run, RunConfig
from mjxskill.runs.layout import KINDS
from mjxskill.evaluation.validation import in_contention, validate

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.protocol import Rollout
    from mjxskill.task import PlannedTask


class TrainClock:
    """A run's training time, added to the experiment's state as each batch reaches the disk (the
    training loop reports a batch once it is written): a process killed mid-run (SIGKILL, where
    no ``finally`` runs) loses the seconds of the batch in flight, not the run's. It is the loop's
    progress reporter, handing every report on to ``inner`` (None: none)."""

    def __init__(self, exp: Experiment, key: str, inner=None):
        self.exp, self.key, self.inner = exp, key, inner
        self.mark = time.monotonic()
        self.simulation, self.rows, self.recorded = 0.0, 0, False  # since the last record

    def evaluator(self, evaluate) -> Callable[[object, int], BatchResult]:
        """``evaluate`` that counts its seconds and rows (the physics' share of the run)."""

        def timed(params, iteration):
            t0 = time.monotonic()
            result = evaluate(params, iteration)
            self.simulation += time.monotonic() - t0
            self.rows += len(params)
            return result

        return timed

    def record(self) -> None:
        """Adds the seconds since the last record (and the rows and physics in them); only once
        the run has evaluated something now (a run resumed with nothing to do adds nothing)."""
        now = time.monotonic()
        if self.rows:
            self.exp.add_time(self.key, "train_seconds", now - self.mark, self.rows)
            self.exp.add_time(self.key, "simulation_seconds", self.simulation, self.rows)
            self.recorded = True
        elif self.recorded:
            self.exp.add_time(self.key, "train_seconds", now - self.mark)
        self.mark, self.simulation, self.rows = now, 0.0, 0

    def start(self, ev, reference) -> None:
        if self.inner:
            self.inner.start(ev, reference)

    def update(self, new, ev, reference) -> None:
        self.record()
        if self.inner:
            self.inner.update(new, ev, reference)

    def close(self) -> None:
        if self.inner:
            self.inner.close()


def train_timed(exp: Experiment, run: Run, rollout: Rollout, progress_for) -> bool:
    """Trains (or finishes) one run, adding its wall and simulation time to the state batch by
    batch (``TrainClock``); True when it evaluated something now."""
    config = run.config()
    clock = TrainClock(exp, time_key(KINDS[config.optimizer], config.seed), progress_for(config))
    try:
        with run.lock():
            ev = train(run, config, clock.evaluator(rollout_evaluator(rollout, config.batch_size, config.seed)), progress=clock)
            write_run_figures(run, config, ev)
    finally:
        clock.record()
    return clock.recorded


def evaluate_timed(exp: Experiment, run: Run, rollout: Rollout, task: PlannedTask, settings: dict, progress=None) -> bool:
    """Evaluates one optimizer run (reused when current); True when it ran now."""
    config = run.config()
    t0 = time.monotonic()
    with run.lock():
        _, _, reused = evaluate_run(run, config, rollout, task, settings, progress=progress)
    if not reused:
        exp.add_time(time_key(KINDS[config.optimizer], config.seed), "evaluate_seconds", time.monotonic() - t0)
    return not reused


def _timed_step(exp: Experiment, run: Run, field: str, step) -> bool:
    """Runs ``step(run_config, front)`` (True: it reused what was on disk) under the run's lock,
    adding its seconds to the state as ``field`` when it rolled something out; True when it did."""
    run_config = run.config()
    t0 = time.monotonic()
    with run.lock():
        reused = step(run_config, run.front(run_config))
    if not reused:
        exp.add_time(time_key(KINDS[run_config.optimizer], run_config.seed), field, time.monotonic() - t0)
    return not reused


def validate_timed(exp: Experiment, run: Run, rollout: Rollout, config: RunConfig, protocol: Protocol, seed: int) -> bool | None:
    """Validates the pick of one evaluated optimizer run (``mjxskill.evaluation.validation``; reused
    when current). True when it ran now, False when reused, None when the protocol has none."""
    settings = repetition_validation(config, protocol, seed)
    if settings is None:
        return None
    return _timed_step(exp, run, "validate_seconds", lambda _, front: validate(
        run, front, in_contention(front, protocol.max_force, protocol.validation_candidates), rollout, settings)[1])


def race_timed(exp: Experiment, run: Run, rollout: Rollout, config: RunConfig, protocol: Protocol, seed: int) -> bool | None:
    """Races the front of one optimizer run of the robust protocol for its pick
    (``mjxskill.evaluation.racing``; finished rounds reused). True when a round ran now, False
    when all were done, None when the run picks by validation instead."""
    settings = repetition_race(config, protocol, seed, len(rollout.scenario.robot.start_configs))
    if settings is None:
        return None

    def step(run_config, front) -> bool:
        if load_race(run.path, front, settings) is not None:
            return True
        race(run.path, front, rollout, settings, run_config.batch_size)
        return False

    return _timed_step(exp, run, "race_seconds", step)


def confirm_timed(exp: Experiment, run: Run, rollout: Rollout, task: PlannedTask, config: RunConfig, protocol: Protocol, seed: int,
                  pick_row: int | None) -> bool | None:
    """Rolls the pick (``pick_row`` of the front; None: no pick) and the operators' sets out in
    the protocol's confirmation worlds (``mjxskill.evaluation.confirmation``; reused when
    current). True when it ran now, False when reused, None when the protocol has none."""
    settings = repetition_confirmation(config, protocol, seed)
    if settings is None:
        return None
    return _timed_step(exp, run, "confirm_seconds", lambda run_config, front: confirm(
        run.path, rollout, confirmation_candidates(task, None if pick_row is None else front.params[pick_row]),
        settings, run_config.batch_size)[1])


def share_cluster(cpus: int, pending: int) -> tuple[int, int]:
    """(repetitions run at the same time, Ray actors of each) on a cluster of ``cpus`` CPUs with
    ``pending`` repetitions left: one actor per CPU in all, at least one each."""
    at_a_time = max(1, min(int(pending), int(cpus)))
    return at_a_time, max(1, int(cpus) // at_a_time)


def pending_repetitions(exp: Experiment) -> int:
    """How many repetitions are not finished yet (trained, evaluated and validated)."""
    config = exp.config()
    return len(exp.runs(config)) - len(finished_repetitions(exp, config, exp.protocol()))


def run_repetition(exp: Experiment, i: int, rollout: Rollout, task: PlannedTask, *, progress_for, log: Callable[[str], None],
                   evaluation_progress=None) -> None:
    """Runs (or finishes) repetition ``i``: its optimizer run, its random search, the optimizer
    run's evaluation and the validation of its pick, recording the wall-clock interval it
    worked in (when it did something, or was interrupted)."""
    config, protocol = exp.config(), exp.protocol()
    pairs = exp.runs(config)
    opt, rnd = pairs[i]
    seed = config.seed + i
    said = f"repetition {i + 1} of {len(pairs)} (seed {seed})"
    started, ran = time.time(), False
    try:
        log(f"{said}: optimizer")
        ran |= train_timed(exp, opt, rollout, progress_for)
        log(f"{said}: random search")
        ran |= train_timed(exp, rnd, rollout, progress_for)
        log(f"{said}: evaluation")
        ran |= evaluate_timed(exp, opt, rollout, task, repetition_settings(config, protocol, seed), evaluation_progress)
        if config.protocol == "robust":
            log(f"{said}: race of the front for the pick")
            ran |= bool(race_timed(exp, opt, rollout, config, protocol, seed))
        elif protocol.validation_per_config:
            log(f"{said}: validation of the pick")
            ran |= bool(validate_timed(exp, opt, rollout, config, protocol, seed))
        if protocol.confirm_per_config:
            log(f"{said}: confirmation of the pick in {protocol.confirm_per_config} worlds per start configuration")
            ran |= bool(confirm_timed(exp, opt, rollout, task, config, protocol, seed, repetition_pick(exp, i)))
    except BaseException:
        exp.add_interval(seed, started, time.time(), interrupted=True)
        raise
    if ran:
        exp.add_interval(seed, started, time.time())


def run_experiment(exp: Experiment, rollout: Rollout | list[Rollout] | tuple[Rollout, ...], task: PlannedTask, *,
                   progress_for, log: Callable[[str], None],
                   evaluation_progress=None) -> None:
    """Runs (or continues) every repetition of ``exp`` to its end and writes the report after
    each. ``rollout``: one rollout (the repetitions one after another), or a list of them (as
    many repetitions at a time, each on one of them: the module docstring);
    ``progress_for(config)``: the training loop's progress reporter for a run; ``log(text)``: a
    line for the user; ``evaluation_progress(done, total)`` per chunk."""
    config = exp.config()
    count = len(exp.runs(config))
    rollouts = list(rollout) if isinstance(rollout, (list, tuple)) else [rollout]
    steps = dict(progress_for=progress_for, log=log, evaluation_progress=evaluation_progress)
    if len(rollouts) == 1:
        for i in range(count):
            run_repetition(exp, i, rollouts[0], task, **steps)
            log(write_report(exp))
    else:
        _concurrently(exp, rollouts, count, task, steps)
    for repeated in (exp.optimizer, exp.random_search):
        if config.repeats > 1:
            log(write_repeats(repeated, repeated.config(), [p for p in repeated.sub_runs(repeated.config())]))


class _Turns:
    """A rollout whose episodes run without ``lock`` (held by its repetition's thread otherwise):
    the episodes of several repetitions run at the same time on the cluster, and all else in
    this process one thread at a time (the module docstring). The calls the training loop and
    the evaluations make: ``__call__``, ``run_worlds``; the rest is the rollout's own."""

    def __init__(self, rollout: Rollout, lock: threading.Lock):
        self._rollout, self._lock = rollout, lock

    def __getattr__(self, name):
        return getattr(self._rollout, name)

    def __call__(self, params, key):
        params = self._rollout.check_params(params)  # as the rollout's own __call__, its worlds drawn in turn
        return self.run_worlds(params, self._rollout.sample_worlds(key, len(params)))

    def run_worlds(self, params, worlds, **how):
        self._lock.release()
        try:
            return self._rollout.run_worlds(params, worlds, **how)
        finally:
            self._lock.acquire()


def _concurrently(exp: Experiment, rollouts: Sequence[Rollout], count: int, task: PlannedTask, steps: dict) -> None:
    """Repetitions 0..count-1 on one thread per rollout, taking turns but for their episodes;
    the report after each (here, in turn too)."""
    turn = threading.Lock()
    todo: queue.SimpleQueue = queue.SimpleQueue()
    for i in range(count):
        todo.put(i)
    finished: queue.SimpleQueue = queue.SimpleQueue()  # (i, None or the exception that stopped it)
    stop = threading.Event()

    def work(rollout: Rollout) -> None:
        while not stop.is_set():
            try:
                i = todo.get_nowait()
            except queue.Empty:
                return
            try:
                with turn:
                    run_repetition(exp, i, _Turns(rollout, turn), task, **steps)
            except BaseException as err:  # noqa: BLE001  (handed to the main thread, raised there)
                finished.put((i, err))
                return
            finished.put((i, None))

    threads = [threading.Thread(target=work, args=(r,), name=f"mjxskill-repetitions-{k}", daemon=True)
               for k, r in enumerate(rollouts)]
    try:
        for thread in threads:
            thread.start()
        for _ in range(count):
            while True:  # a timeout, so that Ctrl-C is raised here while the threads work
                try:
                    i, err = finished.get(timeout=0.5)
                    break
                except queue.Empty:
                    if not any(t.is_alive() for t in threads) and finished.empty():
                        raise RuntimeError("the experiment's repetition threads ended with repetitions left") from None
            if err is not None:
                raise err
            with turn:
                said = write_report(exp)
            steps["log"](said)
    except BaseException:
        stop.set()
        for rollout in rollouts:
            rollout.close()  # stops their Ray work now; a call running in a thread fails at once
        for thread in threads:
            thread.join(timeout=60)
        for rollout in rollouts:
            rollout.close()  # a pool a thread started just before it saw the stop
        raise


__all__ = ["evaluate_timed", "pending_repetitions", "run_experiment", "run_repetition", "share_cluster", "train_timed",
           "validate_timed"]
