"""A training run on disk: its configuration, its evaluations, and how it resumes.

Layout of a run directory::

    config.yaml          resolved scenario summary and flags (the run's identity)
    scenario.yaml        verbatim copy of the scenario file that was trained
    domain.pddl, problem.pddl, plan.txt, bt.txt
    evaluations.csv      one row per evaluation, appended and flushed batch by batch
    pareto.csv           the non-dominated rows of evaluations.csv
    optimizer_state.npz  the GP optimizer's state (``mjxskill.gp.save_state``)
    run_state.json       the hypervolume reference point, fixed after the warm-up

``evaluations.csv`` is the source of truth: a run is resumed by replaying its rows into a fresh
optimizer state, so a run killed at any moment loses at most the batch it was evaluating, and
the replayed state is bit-identical to the uninterrupted one (floats are written with 17
significant digits, which round-trips float64 exactly).
"""

from __future__ import annotations

import csv
import io
import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Iterator, NamedTuple

import numpy as np
import yaml

from mjxskill.errors import RunError

CONFIG = "config.yaml"
SCENARIO_COPY = "scenario.yaml"
EVALUATIONS = "evaluations.csv"
PARETO = "pareto.csv"
OPTIMIZER_STATE = "optimizer_state.npz"
RUN_STATE = "run_state.json"
FORMAT = "mjxskill.run/1"


@dataclass(frozen=True)
class RunConfig:
    """What a run is: the task, its parameter space and objectives, and the training flags.

    task: scenario name ("push"); scenario: what ``load_scenario`` was given (a name or a path).
    engine: the physics engine the run's batches are evaluated on (``mjxskill.engines``).
    bounds: ((lower...), (upper...)) in parameter order. optimizer_options: settings of the GP
    optimizer other than the defaults (``--optimizer-option``). repeats > 1: this directory holds one
    sub-run per seed (``seed-<s>/``) and no evaluations of its own.
    """

    task: str
    scenario: str
    goal: str
    parameter_names: tuple[str, ...]
    parameter_units: tuple[str, ...]
    bounds: tuple[tuple[float, ...], tuple[float, ...]]
    objective_names: tuple[str, ...]
    budget: int
    batch_size: int
    n_init: int
    worlds: int
    seed: int
    episode_seconds: float
    repeats: int = 1
    optimizer_options: dict = field(default_factory=dict)  # further mjxskill.gp.MOBOConfig fields
    engine: str = "mjx"  # "mjx" or "native" (mjxskill.engines); runs from before the setting were MJX

    def to_yaml(self) -> str:
        data = {"format": FORMAT, **asdict(self)}
        data["parameter_names"] = list(self.parameter_names)
        data["parameter_units"] = list(self.parameter_units)
        data["bounds"] = [list(self.bounds[0]), list(self.bounds[1])]
        data["objective_names"] = list(self.objective_names)
        data["optimizer_options"] = dict(self.optimizer_options)
        return yaml.safe_dump(data, sort_keys=False)

    @classmethod
    def from_yaml(cls, text: str, where: str) -> "RunConfig":
        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as err:
            raise RunError(f"{where} is not valid YAML: {err}") from None
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise RunError(f"{where} is not an mjxskill run configuration (format {FORMAT!r} expected)")
        data = dict(data)
        data.pop("format")
        try:
            return cls(
                task=str(data["task"]),
                scenario=str(data["scenario"]),
                goal=str(data["goal"]),
                parameter_names=tuple(map(str, data["parameter_names"])),
                parameter_units=tuple(map(str, data["parameter_units"])),
                bounds=(tuple(map(float, data["bounds"][0])), tuple(map(float, data["bounds"][1]))),
                objective_names=tuple(map(str, data["objective_names"])),
                budget=int(data["budget"]),
                batch_size=int(data["batch_size"]),
                n_init=int(data["n_init"]),
                worlds=int(data["worlds"]),
                seed=int(data["seed"]),
                episode_seconds=float(data["episode_seconds"]),
                repeats=int(data.get("repeats", 1)),
                optimizer_options=dict(data.get("optimizer_options") or {}),
                engine=_engine(data.get("engine", "mjx"), where),
            )
        except (KeyError, TypeError, ValueError, IndexError) as err:
            raise RunError(f"{where} is missing or has a bad field: {err}") from None

    def columns(self) -> list[str]:
        """Header of evaluations.csv and pareto.csv."""
        return evaluation_columns(self.parameter_names, self.objective_names)

    def sub_run(self, seed: int) -> "RunConfig":
        """The configuration of repeat ``seed`` of a repeated run."""
        from dataclasses import replace

        return replace(self, seed=seed, repeats=1)


def _engine(value, where: str) -> str:
    from mjxskill.engines import ENGINES

    if value not in ENGINES:
        raise RunError(f"{where}: engine {value!r} is not one of {', '.join(ENGINES)}")
    return str(value)


def evaluation_columns(parameter_names, objective_names) -> list[str]:
    return ["iteration", *parameter_names, *(f"objective_{o}" for o in objective_names), "success_rate", "max_force"]


def batch_sizes(budget: int, batch_size: int, n_init: int) -> Iterator[int]:
    """Sizes of the successive batches of a run, as ``mjxskill.gp.ask`` proposes them: the
    warm-up stops at exactly ``n_init`` points and the last batch is cut to the budget."""
    n = 0
    while n < budget:
        q = min(batch_size, budget - n)
        if n < n_init:
            q = min(q, n_init - n)
        yield q
        n += q


class Evaluations(NamedTuple):
    """The rows of evaluations.csv. n rows, P parameters, O objectives.

    iteration (n,) int: batch index. params (n, P) float64. objectives (n, O) float64, larger
    is better. success_rate (n,) float64 in [0, 1]. max_force (n,) float64, N (the largest
    feed-forward force the skills commanded in an episode, mean over the worlds).
    """

    iteration: np.ndarray
    params: np.ndarray
    objectives: np.ndarray
    success_rate: np.ndarray
    max_force: np.ndarray

    def __len__(self) -> int:  # type: ignore[override]
        return len(self.iteration)

    @classmethod
    def empty(cls, n_params: int, n_objectives: int) -> "Evaluations":
        return cls(np.zeros(0, int), np.zeros((0, n_params)), np.zeros((0, n_objectives)), np.zeros(0), np.zeros(0))

    def take(self, index) -> "Evaluations":
        return Evaluations(*(np.asarray(a)[index] for a in self))

    def concat(self, other: "Evaluations") -> "Evaluations":
        return Evaluations(*(np.concatenate([a, b]) for a, b in zip(self, other)))


def _format(value: float) -> str:
    return repr(float(value))  # shortest string that round-trips the float64 exactly


def format_rows(ev: Evaluations) -> str:
    """CSV text (no header) of ``ev``."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    for i in range(len(ev)):
        writer.writerow(
            [int(ev.iteration[i]), *map(_format, ev.params[i]), *map(_format, ev.objectives[i]),
             _format(ev.success_rate[i]), _format(ev.max_force[i])]
        )
    return out.getvalue()


def write_csv(path: Path, columns: list[str], ev: Evaluations) -> None:
    """Writes a whole CSV atomically (temporary file + rename)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(",".join(columns) + "\n" + format_rows(ev))
    os.replace(tmp, path)


def append_rows(path: Path, ev: Evaluations) -> None:
    """Appends ``ev`` to a CSV in one write and forces it to disk before returning."""
    with open(path, "a") as fh:
        fh.write(format_rows(ev))
        fh.flush()
        os.fsync(fh.fileno())


def read_csv(path: Path, columns: list[str]) -> Evaluations:
    """Reads a CSV written by this module; a torn last line (a kill mid-write) is ignored."""
    text = path.read_text()
    lines = text.split("\n")
    if not text.endswith("\n"):
        lines = lines[:-1]  # the last line was cut short
    rows = list(csv.reader([line for line in lines if line]))
    if not rows or rows[0] != columns:
        raise RunError(
            f"{path} does not have the columns this task expects: got {rows[0] if rows else 'nothing'}, "
            f"expected {columns}"
        )
    p = sum(1 for c in columns[1:] if not c.startswith("objective_") and c not in ("success_rate", "max_force"))
    o = sum(1 for c in columns if c.startswith("objective_"))
    body = [row for row in rows[1:] if len(row) == len(columns)]
    try:
        data = np.array([[float(v) for v in row] for row in body], np.float64)
    except ValueError as err:
        raise RunError(f"{path} holds a value that is not a number: {err}") from None
    data = data.reshape(-1, len(columns))
    return Evaluations(data[:, 0].astype(int), data[:, 1 : 1 + p], data[:, 1 + p : 1 + p + o], data[:, 1 + p + o], data[:, 2 + p + o])


class Run:
    """A run directory (see the module docstring)."""

    def __init__(self, path: Path | str):
        self.path = Path(path)

    # -- creation and identity -----------------------------------------------------------------
    def create(self, config: RunConfig, scenario_source: str, texts: dict[str, str]) -> None:
        """Writes config.yaml, the scenario copy, the planning artefacts ``texts`` (file name ->
        text) and the header of evaluations.csv. Refuses a directory that already holds a run."""
        if (self.path / CONFIG).exists():
            raise RunError(f"{self.path} already holds a run; continue it with --resume {self.path}")
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            (self.path / SCENARIO_COPY).write_text(Path(scenario_source).read_text())
            for name, text in texts.items():
                (self.path / name).write_text(text if text.endswith("\n") else text + "\n")
            if config.repeats == 1:
                write_csv(self.path / EVALUATIONS, config.columns(), Evaluations.empty(len(config.parameter_names), len(config.objective_names)))
            # config.yaml last: its presence marks a complete run directory.
            (self.path / CONFIG).write_text(config.to_yaml())
        except OSError as err:
            raise RunError(f"cannot write the run directory {str(self.path)!r}: {err.strerror}") from None

    def config(self) -> RunConfig:
        path = self.path / CONFIG
        if not path.is_file():
            raise RunError(f"{self.path} is not a run directory (no {CONFIG})")
        return RunConfig.from_yaml(path.read_text(), str(path))

    # -- evaluations ---------------------------------------------------------------------------
    def evaluations(self, config: RunConfig | None = None) -> Evaluations:
        """The complete batches on disk (an incomplete last batch, left by a kill, is dropped)."""
        config = self.config() if config is None else config
        ev = read_csv(self.path / EVALUATIONS, config.columns())
        keep, n = 0, 0
        for batch, size in enumerate(batch_sizes(config.budget, config.batch_size, config.n_init)):
            rows = ev.iteration[n : n + size]
            if len(rows) < size or np.any(rows != batch):
                break
            n += size
            keep = n
        return ev.take(slice(0, keep))

    def repair(self, config: RunConfig) -> Evaluations:
        """Rewrites evaluations.csv without rows beyond the last complete batch; returns the rows."""
        ev = self.evaluations(config)
        on_disk = read_csv(self.path / EVALUATIONS, config.columns())
        if len(on_disk) != len(ev) or not (self.path / EVALUATIONS).read_text().endswith("\n"):
            write_csv(self.path / EVALUATIONS, config.columns(), ev)
        return ev

    def append(self, ev: Evaluations) -> None:
        append_rows(self.path / EVALUATIONS, ev)

    def write_pareto(self, config: RunConfig, ev: Evaluations, mask: np.ndarray) -> None:
        write_csv(self.path / PARETO, config.columns(), ev.take(mask))

    def pareto(self, config: RunConfig | None = None) -> Evaluations:
        config = self.config() if config is None else config
        path = self.path / PARETO
        if not path.is_file():
            raise RunError(f"{self.path} has no {PARETO} yet (train it first)")
        return read_csv(path, config.columns())

    # -- small state ---------------------------------------------------------------------------
    def run_state(self) -> dict:
        path = self.path / RUN_STATE
        return json.loads(path.read_text()) if path.is_file() else {}

    def write_run_state(self, state: dict) -> None:
        tmp = self.path / (RUN_STATE + ".tmp")
        tmp.write_text(json.dumps(state, indent=1))
        os.replace(tmp, self.path / RUN_STATE)

    def sub_runs(self, config: RunConfig) -> list["Run"]:
        return [Run(self.path / f"seed-{config.seed + i}") for i in range(config.repeats)]
