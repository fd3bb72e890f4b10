"""A training run on disk: its configuration, its evaluations, and how it resumes.

Layout of a run directory::

    config.yaml          resolved scenario summary and flags (the run's identity)
    scenario.yaml        verbatim copy of the scenario file that was trained
    domain.pddl, problem.pddl, plan.txt, bt.txt
                         the planned task (``mjxskill.task.planning_texts``), for the reader: nothing
                         reads them back; a run of an experiment has none (the experiment holds
                         them once, ``mjxskill.runs.layout``)
    evaluations.csv      one row per evaluation, appended and flushed batch by batch
    pareto.csv           the non-dominated rows of evaluations.csv
    optimizer_state.npz  the GP optimizer's state (``mjxskill.gp.save_state``)
    run_state.json       the hypervolume reference point, fixed after the warm-up
    .lock                the writer's lock and who holds it (run_lock)
    evaluations.csv.orig-<n>, evaluations-set-aside.csv
                         after a resume that could not use every line (resume)
    scenario.yaml.orig-<n> the copy before a resume accepted another scenario (run_task)

``evaluations.csv`` is the source of truth: a run is resumed by replaying its rows into a fresh
optimizer state, so a run killed at any moment loses at most the batch it was evaluating, and
the replayed state is bit-identical to the uninterrupted one (floats are written with 17
significant digits, which round-trips float64 exactly). Rows that cannot be used are never
dropped silently (``mjxskill.runs.resume``).

A run directory is created whole or not at all (built beside it in a staging folder named after
the host and process, then renamed into place; a staging folder that a process killed on this
host left behind is removed at the next creation beside it), only where nothing is (a missing or empty folder: another folder is the user's and is refused), and
written by one process at a time (``lock``, ``mjxskill.runs.run_lock``). Every file is
checked when read: a damaged one is a ``RunError`` naming it.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from mjxskill._files import is_regular, read_regular
from mjxskill.errors import RunError
from mjxskill.scenario.fields import read_text
from mjxskill.runs.atomic_write import (  # noqa: F401  (STAGING, _this_host: re-exported, where they lived before)
    STAGING,
    _this_host,
    check_folder,
    created_whole,
    remove_stale_staging,
    write_text,
)
from mjxskill.runs.evaluations_csv import (  # noqa: F401  (re-exported: the run's CSV format)
    Batches,
    Evaluations,
    append_rows,
    assign_batches,
    concat_all,
    parse,
    read_bytes,
    read_csv,
    write_csv,
)
from mjxskill.runs.run_config import FORMAT, RunConfig, batch_sizes, evaluation_columns  # noqa: F401
from mjxskill.runs.run_lock import LOCK_FILE, RunLock, lock_run

CONFIG = "config.yaml"
SCENARIO_COPY = "scenario.yaml"
EVALUATIONS = "evaluations.csv"
PARETO = "pareto.csv"
OPTIMIZER_STATE = "optimizer_state.npz"
RUN_STATE = "run_state.json"


class Run:
    """A run directory (see the module docstring)."""

    def __init__(self, path: Path | str):
        self.path = Path(path)

    # -- creation and identity -----------------------------------------------------------------
    def create(self, config: RunConfig, scenario_source: str, texts: dict[str, str]) -> None:
        """Writes config.yaml, the scenario copy, the planning artefacts ``texts`` (file name ->
        text; {} for the runs of an experiment, which holds them once) and the header of
        evaluations.csv (with ``repeats`` > 1: one sub-run per seed, each with ``texts`` too).
        Refuses a directory that holds a run or anything else; writes all or nothing."""
        self._check_free()
        # on a failure, another process may have got there first: say so
        with created_whole(self.path, "run directory", on_failure=self._check_free) as staging:
            scenario_text = read_regular(scenario_source).decode()  # loaded already: a regular UTF-8 file
            _write_run(staging, config, scenario_text, texts)
            for sub in Run(staging).sub_runs(config) if config.repeats > 1 else []:
                sub.path.mkdir()
                _write_run(sub.path, config.sub_run(int(sub.path.name.split("-")[1])), scenario_text, texts)

    def _check_free(self) -> None:
        if os.path.lexists(self.path / CONFIG):
            raise RunError(f"{self.path} already holds a run; continue it with --resume {self.path}")
        if self.path.exists() and not self.path.is_dir():
            raise RunError(f"{self.path} exists and is not a directory; choose another --out")
        if self.path.is_dir():
            entries = sorted(os.listdir(self.path))
            if entries:
                shown = ", ".join(entries[:5]) + (f" and {len(entries) - 5} more" if len(entries) > 5 else "")
                raise RunError(f"{self.path} is not empty and holds no mjxskill run ({shown}); refusing to write "
                               f"into it: choose another --out")

    def config(self) -> RunConfig:
        path = self.path / CONFIG
        if not is_regular(path, RunError):
            raise RunError(f"{self.path} is not a run directory (no {CONFIG})")
        return RunConfig.from_yaml(read_text(path, RunError, "run configuration"), str(path))

    def check(self, config: RunConfig) -> None:
        """Reads every file a resume reads (the sub-runs' too), so that a damaged or missing one
        is a RunError now, before anything is compiled; changes nothing."""
        for run in self.sub_runs(config) if config.repeats > 1 else [self]:
            own = run.config() if run is not self else config
            run.run_state()
            run.batches(own)
            for name in (PARETO, OPTIMIZER_STATE):  # replaced after the next batch: a FIFO there is refused now
                is_regular(run.path / name, RunError)

    def lock(self) -> RunLock:
        """The writer's lock of this run (RunError naming the holder if another process has it)."""
        return lock_run(self.path)

    # -- evaluations ---------------------------------------------------------------------------
    def batches(self, config: RunConfig) -> Batches:
        """evaluations.csv sorted into the run's batches, with every line that is not used."""
        path = self.path / EVALUATIONS
        parsed = parse(read_bytes(path), config.columns(), config.bounds, str(path))
        return assign_batches(parsed, list(batch_sizes(config.training_rows, config.batch_size, config.n_init)))

    def evaluations(self, config: RunConfig | None = None) -> Evaluations:
        """The complete batches on disk in batch order (nothing is changed on disk; resuming is
        ``mjxskill.runs.resume``'s)."""
        config = self.config() if config is None else config
        batches = self.batches(config)
        return concat_all(batches.complete.values(), len(config.parameter_names), len(config.objective_names),
                          config.pooled)

    def append(self, ev: Evaluations) -> None:
        append_rows(self.path / EVALUATIONS, ev)

    def write_evaluations(self, config: RunConfig, ev: Evaluations) -> None:
        """Replaces evaluations.csv with ``ev`` in one step (a batch filled in before others)."""
        write_csv(self.path / EVALUATIONS, config.columns(), ev)

    def write_pareto(self, config: RunConfig, ev: Evaluations, mask: np.ndarray) -> None:
        write_csv(self.path / PARETO, config.columns(), ev.take(mask))

    def pareto(self, config: RunConfig | None = None) -> Evaluations:
        config = self.config() if config is None else config
        path = self.path / PARETO
        if not is_regular(path, RunError):
            raise RunError(f"{self.path} has no {PARETO} yet (train it first)")
        return read_csv(path, config.columns(), config.bounds)

    def front(self, config: RunConfig) -> Evaluations:
        """The Pareto front to evaluate or select from; RunError when it has no rows yet."""
        front = self.pareto(config)
        if len(front) == 0:
            raise RunError(f"{self.path} has an empty Pareto front ({PARETO} has no rows: no evaluations yet); "
                           f"train it first (--resume {self.path})")
        return front

    # -- small state ---------------------------------------------------------------------------
    def run_state(self) -> dict:
        """run_state.json ({} before the warm-up is complete); RunError if it is damaged."""
        path = self.path / RUN_STATE
        if not is_regular(path, RunError):
            return {}
        hint = "delete it and --resume recomputes it from the warm-up rows"
        try:
            state = json.loads(read_text(path, RunError, "run state"))
        except ValueError as err:
            raise RunError(f"{path} is not valid JSON ({err}); {hint}") from None
        ref = state.get("hv_reference") if isinstance(state, dict) else None
        if not isinstance(state, dict) or (ref is not None and not (
                isinstance(ref, list) and all(isinstance(v, (int, float)) and math.isfinite(v) for v in ref))):
            raise RunError(f"{path} is not a run state (hv_reference must be a list of finite numbers); {hint}")
        return state

    def write_run_state(self, state: dict) -> None:
        write_text(self.path / RUN_STATE, json.dumps(state, indent=1))

    def sub_runs(self, config: RunConfig) -> list["Run"]:
        """The repetitions ``seed-<s>``; RunError naming one that is a symbolic link (even to a
        folder inside the run: its files would be written into another repetition)."""
        subs = [Run(self.path / f"seed-{config.seed + i}") for i in range(config.repeats)]
        for sub in subs:
            check_folder(self.path, sub.path)
        return subs


def write_texts(folder: Path, texts: dict[str, str]) -> None:
    """Writes each text of ``texts`` (file name -> text, ended by a newline) into ``folder``, a
    staging folder being created (``created_whole``): a run's or an experiment's planning files."""
    for name, text in texts.items():
        (folder / name).write_text(text if text.endswith("\n") else text + "\n")


def _write_run(folder: Path, config: RunConfig, scenario_text: str, texts: dict[str, str]) -> None:
    (folder / SCENARIO_COPY).write_text(scenario_text)
    write_texts(folder, texts)
    if config.repeats == 1:
        write_csv(folder / EVALUATIONS, config.columns(), Evaluations.empty(len(config.parameter_names), len(config.objective_names),
                                                                         config.pooled))
    (folder / CONFIG).write_text(config.to_yaml())


__all__ = ["CONFIG", "EVALUATIONS", "FORMAT", "LOCK_FILE", "OPTIMIZER_STATE", "PARETO", "RUN_STATE", "SCENARIO_COPY",
           "Evaluations", "Run", "RunConfig", "batch_sizes", "created_whole", "evaluation_columns", "read_csv", "remove_stale_staging",
           "write_csv", "write_texts"]
