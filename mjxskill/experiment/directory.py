"""An experiment directory: its protocol (``experiment.yaml``), its two repeated runs, its state.

Layout: ``mjxskill.runs.layout``. The planned task's files (``domain.pddl``, ``problem.pddl``,
``plan.txt``, ``bt.txt``) are written once, in the experiment directory: its runs, all of one
task, hold no copies of them. ``experiment.yaml`` holds what the runs' ``config.yaml``
files do not: how each repetition is evaluated (worlds per start configuration, random sets,
the pick's force bound and its validation; the validation alone may be changed when the
experiment is resumed, ``Experiment.set_validation``). The training settings are the runs' own: ``optimizer/config.yaml``
and ``random_search/config.yaml`` are one configuration that differs only in ``optimizer``.
``state.json`` accumulates the wall time spent on each run and evaluation, over every session
(a resumed experiment adds to it), and per repetition the wall-clock intervals it worked in
(``repetitions``: ``seed-<s>`` -> a list of ``started``/``ended``, seconds since the epoch, one
per session that trained, evaluated or validated something of it; ``interrupted`` where the
session stopped inside it): on a Ray cluster the repetitions run at the same time and their
intervals overlap. The state is written under a lock: the repetitions' threads share it. Like a run, an experiment is created whole or not at all,
only where nothing is, and written by one process at a time.
"""

from __future__ import annotations

import json
import math
import os
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import yaml

from mjxskill._files import is_regular
from mjxskill.errors import RunError, quote
from mjxskill.scenario.fields import compose_text, read_text
from mjxskill.runs.atomic_write import write_json, write_text
from mjxskill.evaluation.evaluate_run import evaluation_settings
from mjxskill.runs.run_dir import Run, RunConfig, created_whole, write_texts
from mjxskill.runs.run_lock import RunLock, lock_run
from mjxskill.evaluation.pooled import GIVEN, force_bound
from mjxskill.evaluation.confirmation import confirmation_settings
from mjxskill.evaluation.racing import race_settings
from mjxskill.evaluation.validation import validation_settings
from mjxskill.runs.training_protocol import race_episodes
from mjxskill.runs.layout import EXPERIMENT, OPTIMIZER_RUNS, RANDOM_RUNS
from mjxskill.runs.bounds import MAX_PER_CONFIG, MAX_RANDOM_SETS, MAX_VALIDATION_CANDIDATES

FORMAT = "mjxskill.experiment/1"
STATE = "state.json"


@dataclass(frozen=True)
class Protocol:
    """How each repetition is evaluated. per_config: worlds from each known and each unseen
    start configuration; random_sets: uniform parameter sets; max_force: the pick's force bound,
    N (None: unbounded), settled when the experiment is made (``--max-force``, else the
    scenario's ``pick.max_force``); max_force_source: where it came from, in words (None in an
    experiment.yaml written before the bound was stated, whose null meant the largest force an
    operator set commands: ``Experiment.settle_bound`` replaces it with the scenario's);
    validation_per_config: fresh worlds from each known start configuration in which the
    validation_candidates best solutions within the bound are rolled out again before the pick
    (``mjxskill.evaluation.validation``; 0: the training success alone decides, as in an
    experiment.yaml written before validation existed, which has neither key); a run of the
    robust protocol picks by its race instead (``mjxskill.evaluation.racing``).
    confirm_per_config: worlds from each known and unseen start configuration in which the
    pick and the operators' sets are rolled out after the pick (``mjxskill.evaluation.confirmation``;
    0: none, as in an experiment.yaml written before it existed)."""

    per_config: int = 5
    random_sets: int = 10
    max_force: float | None = None
    validation_per_config: int = 5
    validation_candidates: int = 3
    max_force_source: str | None = None
    confirm_per_config: int = 0

    def to_yaml(self, task: str) -> str:
        return yaml.safe_dump({"format": FORMAT, "task": task, "per_config": self.per_config,
                               "random_sets": self.random_sets, "max_force": self.max_force,
                               "validation_per_config": self.validation_per_config,
                               "validation_candidates": self.validation_candidates,
                               "max_force_source": self.max_force_source,
                               **({"confirm_per_config": self.confirm_per_config} if self.confirm_per_config else {})},
                              sort_keys=False)

    @classmethod
    def from_yaml(cls, text: str, where: str) -> "Protocol":
        root = compose_text(text, where, RunError)
        f = root.mapping(required=("format", "task", "per_config", "random_sets", "max_force"),
                         optional=("validation_per_config", "validation_candidates", "max_force_source",
                                   "confirm_per_config"))
        if f["format"].is_null() or f["format"].scalar() != FORMAT:
            f["format"].fail(f"not an mjxskill experiment (format {FORMAT!r} expected)")
        max_force = None if f["max_force"].is_null() else f["max_force"].number(nonnegative=True)
        source: str | None
        if "max_force_source" in f and not f["max_force_source"].is_null():
            source = f["max_force_source"].string()
        else:  # written before the source was kept: a number was --max-force's; null is unsettled
            source = None if max_force is None else GIVEN
        return cls(per_config=f["per_config"].integer(minimum=1, maximum=MAX_PER_CONFIG),
                   random_sets=f["random_sets"].integer(minimum=0, maximum=MAX_RANDOM_SETS),
                   max_force=max_force, max_force_source=source,
                   validation_per_config=f["validation_per_config"].integer(minimum=0, maximum=MAX_PER_CONFIG) if "validation_per_config" in f else 0,
                   validation_candidates=f["validation_candidates"].integer(minimum=1, maximum=MAX_VALIDATION_CANDIDATES) if "validation_candidates" in f else 3,
                   confirm_per_config=f["confirm_per_config"].integer(minimum=0, maximum=MAX_PER_CONFIG) if "confirm_per_config" in f else 0)


def random_search_config(config: RunConfig) -> RunConfig:
    """The random search that goes with optimizer configuration ``config``."""
    return replace(config, optimizer="random")


def runs_of(run: Run, config: RunConfig) -> list[Run]:
    """The runs a (repeated or single) run directory holds, in seed order."""
    return run.sub_runs(config) if config.repeats > 1 else [run]


class Experiment:
    """An experiment directory (see the module docstring)."""

    def __init__(self, path: Path | str):
        self.path = Path(path)
        self.optimizer = Run(self.path / OPTIMIZER_RUNS)
        self.random_search = Run(self.path / RANDOM_RUNS)
        self._state_lock = threading.RLock()  # one read-modify-write of state.json at a time

    def create(self, config: RunConfig, protocol: Protocol, scenario_source: str, texts: dict[str, str]) -> None:
        """Writes experiment.yaml, the planning artefacts ``texts`` (file name -> text) and the
        two repeated runs of ``config`` (optimizer "mobo"), which get none of their own; all or
        nothing, and only where nothing is (a missing or empty folder)."""
        if os.path.lexists(self.path / EXPERIMENT):
            raise RunError(f"{self.path} already holds an experiment; continue it with --resume {self.path}")
        if self.path.exists() and (not self.path.is_dir() or os.listdir(self.path)):
            raise RunError(f"{self.path} is not empty and holds no mjxskill experiment; refusing to write into it: "
                           f"choose another --out")
        with created_whole(self.path, "experiment directory") as staging:
            write_texts(staging, texts)
            Run(staging / OPTIMIZER_RUNS).create(replace(config, optimizer="mobo"), scenario_source, {})
            Run(staging / RANDOM_RUNS).create(random_search_config(config), scenario_source, {})
            (staging / EXPERIMENT).write_text(protocol.to_yaml(config.task))

    def protocol(self) -> Protocol:
        path = self.path / EXPERIMENT
        if not is_regular(path, RunError):
            raise RunError(f"{self.path} is not an experiment directory (no {EXPERIMENT})")
        return Protocol.from_yaml(read_text(path, RunError, "experiment protocol"), str(path))

    def set_validation(self, per_config: int, candidates: int) -> Protocol:
        """Rewrites experiment.yaml with another validation of the pick (the one protocol setting
        a resumed experiment may change: the runs and evaluations do not depend on it, the picks
        are made again from them); returns the new protocol."""
        protocol = replace(self.protocol(), validation_per_config=per_config, validation_candidates=candidates)
        write_text(self.path / EXPERIMENT, protocol.to_yaml(self.config().task))
        return protocol

    def settle_bound(self, stated) -> tuple[Protocol, str | None]:
        """An experiment.yaml written before the pick's bound was stated has ``max_force: null``,
        which meant the largest force an operator set commands (illustrative sets): it gets the
        scenario's bound ``stated`` (``PickBound`` or None), written back with its source, so its
        picks are made again within it (the runs and evaluations are kept). Returns the protocol
        in force and a line saying what changed (None: nothing)."""
        protocol = self.protocol()
        if protocol.max_force_source is not None:
            return protocol, None
        bound, source = force_bound(None, stated)
        new = replace(protocol, max_force=bound, max_force_source=source)
        write_text(self.path / EXPERIMENT, new.to_yaml(self.config().task))
        said = "none" if bound is None else f"{bound:g} N"
        return new, (f"{self.path}: the pick's force bound was the largest force an operator set commands; it is now "
                     f"{said}, {source}; the picks are made again, the runs and evaluations are kept")

    def config(self) -> RunConfig:
        """The training configuration (the optimizer's), checked against the random search's."""
        config = self.optimizer.config()
        other = self.random_search.config()
        if config.optimizer != "mobo" or other != random_search_config(config):
            raise RunError(f"{self.random_search.path / 'config.yaml'} and {self.optimizer.path / 'config.yaml'} "
                           f"must differ only in optimizer (mobo, random): the two would not be comparable")
        return config

    def runs(self, config: RunConfig) -> list[tuple[Run, Run]]:
        """(optimizer run, random search run) per repetition, in seed order."""
        return list(zip(runs_of(self.optimizer, config), runs_of(self.random_search, random_search_config(config))))

    def lock(self) -> RunLock:
        return lock_run(self.path)

    # -- wall times ----------------------------------------------------------------------------
    def state(self) -> dict:
        path = self.path / STATE
        if not is_regular(path, RunError):
            return {"sessions": [], "times": {}}
        try:
            state = json.loads(read_text(path, RunError, "experiment state"))
            _check_state(state)
        except (ValueError, AttributeError) as err:
            raise RunError(f"{path} is not an experiment state ({err}); delete it (only wall times are lost)") from None
        return state

    def add_time(self, key: str, field: str, seconds: float, evaluations: int = 0) -> None:
        """Adds ``seconds`` (and ``evaluations`` computed in them) to ``times[key][field]``."""
        with self._state_lock:
            state = self.state()
            entry = state["times"].setdefault(key, {})
            entry[field] = entry.get(field, 0.0) + float(seconds)
            if evaluations:
                entry[field + "_evaluations"] = entry.get(field + "_evaluations", 0) + int(evaluations)
            self._write_state(state)

    def add_interval(self, seed: int, started: float, ended: float, interrupted: bool = False) -> None:
        """Records that the repetition of seed ``seed`` worked from ``started`` to ``ended``
        (``time.time()`` seconds) in this session."""
        with self._state_lock:
            state = self.state()
            interval = {"started": float(started), "ended": float(ended)}
            if interrupted:
                interval["interrupted"] = True
            state.setdefault("repetitions", {}).setdefault(f"seed-{seed}", []).append(interval)
            self._write_state(state)

    def add_session(self, startup_seconds: float, engine: str, cluster=None, at_a_time: int = 1) -> None:
        """A session's start; ``cluster``: the ``ClusterInfo`` of the Ray cluster it runs on
        (None: this machine) and ``at_a_time`` the repetitions it runs at the same time there."""
        with self._state_lock:
            state = self.state()
            session = {"started": time.strftime("%Y-%m-%d %H:%M:%S"), "startup_seconds": float(startup_seconds),
                       "engine": engine, "cpus": os.cpu_count()}
            if cluster is not None:
                session["ray"] = {"nodes": cluster.nodes, "cpus": cluster.cpus, "repetitions_at_a_time": at_a_time}
            state["sessions"].append(session)
            self._write_state(state)

    def _write_state(self, state: dict) -> None:
        write_json(self.path / STATE, state)


def _number(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value) and value >= 0


SESSION_KEYS = {"started": lambda v: isinstance(v, str), "startup_seconds": _number, "engine": lambda v: isinstance(v, str),
                "cpus": lambda v: v is None or (_number(v) and isinstance(v, int))}


def _check_state(state) -> None:
    """ValueError naming the first entry of state.json that is not what ``add_time`` and
    ``add_session`` write (the report formats every one: a text where a number belongs was a
    TypeError after report.json had been rewritten with it)."""
    if not isinstance(state, dict) or not isinstance(state.get("sessions"), list) or not isinstance(state.get("times"), dict):
        raise ValueError("sessions (a list) and times (a mapping) expected")
    for i, session in enumerate(state["sessions"]):
        if not isinstance(session, dict):
            raise ValueError(f"sessions[{i}] is not a mapping")
        for key, ok in SESSION_KEYS.items():
            if key not in session or not ok(session[key]):
                raise ValueError(f"sessions[{i}].{key} is {quote(session.get(key, 'missing'))}")
    for key, entry in state["times"].items():
        if not isinstance(entry, dict):
            raise ValueError(f"times.{key} is not a mapping")
        for field, value in entry.items():
            if not _number(value):
                raise ValueError(f"times.{key}.{field} is {quote(value)}, not a number of seconds or evaluations")


def repetition_settings(config: RunConfig, protocol: Protocol, seed: int) -> dict:
    """The evaluation settings of the repetition of seed ``seed``: its worlds come from its seed."""
    return evaluation_settings(protocol.per_config, protocol.random_sets, seed, config.batch_size, config.engine,
                               config.episode_seconds)


def repetition_validation(config: RunConfig, protocol: Protocol, seed: int) -> dict | None:
    """The validation settings of the repetition of seed ``seed`` (None: the protocol has none)."""
    if not protocol.validation_per_config:
        return None
    return validation_settings(protocol.validation_per_config, protocol.validation_candidates, seed, config.engine,
                               config.episode_seconds)


def repetition_race(config: RunConfig, protocol: Protocol, seed: int, n_known: int) -> dict | None:
    """The race settings of the repetition of seed ``seed`` (None: its runs are of the paper's
    protocol, whose pick is validated): the race's share of the run's budget, the protocol's bound."""
    if config.protocol != "robust":
        return None
    return race_settings(seed, config.engine, config.episode_seconds, race_episodes(config.budget, config.worlds),
                         protocol.max_force, n_known)


def repetition_confirmation(config: RunConfig, protocol: Protocol, seed: int) -> dict | None:
    """The confirmation settings of the repetition of seed ``seed`` (None: the protocol has none)."""
    if not protocol.confirm_per_config:
        return None
    return confirmation_settings(protocol.confirm_per_config, seed, config.engine, config.episode_seconds)


def is_done(run: Run, config: RunConfig) -> bool:
    return len(run.evaluations(config)) >= config.training_rows


def time_key(kind: str, seed: int) -> str:
    return f"{kind}/seed-{seed}"


__all__ = ["FORMAT", "STATE", "Experiment", "Protocol", "is_done", "random_search_config",
           "repetition_confirmation", "repetition_race", "repetition_settings", "repetition_validation", "runs_of",
           "time_key"]
