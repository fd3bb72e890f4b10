"""On-demand rollouts of one point of a run: success per world and per start configuration, and
a rendered episode, computed in a background thread and kept in the run directory.

A point ``(run, index)`` (row ``index`` of that run's evaluations.csv) is rolled out in the
worlds ``python -m mjxskill.evaluate`` uses (``per_config`` worlds from every known and unseen
start configuration, ``evaluation_worlds``), and rendered in the world ``select`` renders from
(``render_world``: known start configuration ``c``, seed 0). Results go to::

    RUN/explore/evaluation-<index>/worlds.json       per-world success, peak contact force, position error
    RUN/explore/evaluation-<index>/known-<c>/        PNG frames (or known-<c>.mp4 with ffmpeg)
    RUN/explore/evaluation-<index>/known-<c>.json    what was rendered, in which world

Each file records the parameters it was computed for; a file whose parameters are not the
row's (the run was cut and re-trained) is computed again. The rollouts run on the run's own
engine (``config.engine``: the native engine for a run trained on it, MJX for one trained on
MJX) and are closed with the explorer (``Solutions.close``: the native engine's worker
processes). One worker thread runs the jobs one after another (a rollout is not shared between
threads; the CPU is the limit anyway); the server only reads the jobs' progress, so it never
waits for a compile. A point has at most one job queued or running, and at most
``MAX_WAITING_JOBS`` wait: what asks for more is refused (``ServerBusy``), so that a burst of
requests cannot line up hours of rollouts.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from mjxskill.engine import build
from mjxskill.errors import RunError, ServerBusy, UserError
from mjxskill.evaluation.baselines import evaluation_worlds
from mjxskill.evaluation.render import RenderUnavailable, render_episode, render_world
from mjxskill.runs.atomic_write import read_below
from mjxskill.runs.outputs import write_outputs
from mjxskill.runs.run_task import load_run_task
from mjxskill.scenario import load_scenario
from mjxskill.explore.data import RunEntry, number, numbers

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.protocol import Rollout

FORMAT = "mjxskill.explore/1"
CACHE = "explore"
MAX_CACHE_BYTES = 16 * 1024 * 1024  # a cache document is a few KB: a larger file is none
MAX_WAITING_JOBS = 4  # a rollout with rendering takes a minute or more on a CPU
ACTIVE = ("queued", "running")

# (run entry) -> its Rollout, of which the explorer uses scenario, worlds_per_config, run_worlds,
# trace, mj_model and close
RolloutFactory = Callable[[RunEntry], "Rollout"]


def build_for(entry: RunEntry) -> Rollout:
    """The run's rollout on the run's own engine (one world per parameter set; worlds are passed
    explicitly)."""
    scn, task = load_run_task(entry.run, entry.config)
    return build.build_rollout(scn, task, entry.config.engine, worlds=1, episode_seconds=entry.config.episode_seconds)


def _run_of(folder: Path) -> Path:
    """The run whose cache folder (``RUN/explore/evaluation-<i>``) ``folder`` is."""
    return folder.parent.parent


@dataclass
class Job:
    """Progress of one request: state queued | running | done | failed; fraction in [0, 1]."""

    entry: RunEntry
    index: int
    params: np.ndarray
    config_index: int
    state: str = "queued"
    stage: str = "waiting for the job before it"
    fraction: float = 0.0
    message: str = ""
    started: float = field(default_factory=time.monotonic)

    def document(self) -> dict:
        return {"state": self.state, "stage": self.stage, "fraction": round(self.fraction, 3), "message": self.message,
                "elapsed_s": round(time.monotonic() - self.started, 1)}


def _write_json(root: Path, path: Path, doc: dict) -> None:
    """``doc`` into the cache file ``path`` of the run ``root``: the cache is the page's own and
    replaced freely, but never through a link below the run (``write_outputs``)."""
    write_outputs(root, {path: (json.dumps(doc, indent=1) + "\n").encode()}, replace=True)


def read_cached(path: Path, params: np.ndarray, root: Path | None = None, **settings) -> dict | None:
    """The cached document at ``path`` if it was computed for ``params`` with ``settings``; a
    link below ``root`` (default: ``path``'s folder), or no regular file, is no cache."""
    try:
        doc = json.loads(read_below(path.parent if root is None else root, path, limit=MAX_CACHE_BYTES))
    except (OSError, ValueError, RunError):
        return None
    if not isinstance(doc, dict):
        return None
    ok = doc.get("format") == FORMAT and doc.get("params") == numbers(params)
    return doc if ok and all(doc.get(k) == v for k, v in settings.items()) else None


class Solutions:
    """The on-demand rollouts of the points of the runs under ``root`` (see the module doc)."""

    def __init__(self, root: Path, rollout_factory: RolloutFactory = build_for, *, per_config: int = 5, seed: int = 0,
                 size: tuple[int, int] = (640, 480)):
        self.root = Path(root)
        self.rollout_factory = rollout_factory
        self.per_config, self.seed, self.size = per_config, seed, size
        self._lock = threading.Lock()
        self._jobs: dict[tuple, Job] = {}
        self._queue: queue.Queue[Job | None] = queue.Queue()  # None: the worker ends
        self._rollouts: dict[tuple, Rollout] = {}
        self._worker: threading.Thread | None = None
        self._closed = False
        self._known_configs: dict[str, int] = {}  # scenario -> its number of known start configurations
        # Why this process cannot render, once it failed to: the GL backend is fixed when mujoco
        # is imported, and after a failed mjr_makeContext another attempt aborts the process
        # (same thread) or hangs holding the GIL (another thread).
        self._no_video: str | None = None

    # -- where things are ---------------------------------------------------------------------
    @staticmethod
    def folder(entry: RunEntry, index: int) -> Path:
        return entry.run.path / CACHE / f"evaluation-{index}"

    def url(self, path: Path) -> str:
        return "/files/" + Path(os.path.relpath(path, self.root)).as_posix()

    def cached_worlds(self, folder: Path, params: np.ndarray) -> dict | None:
        return read_cached(folder / "worlds.json", params, _run_of(folder), per_config=self.per_config, seed=self.seed)

    def cached_video(self, folder: Path, params: np.ndarray, config_index: int) -> dict | None:
        return read_cached(folder / f"known-{config_index}.json", params, _run_of(folder), seed=self.seed, size=list(self.size))

    def check_config(self, entry: RunEntry, config_index: int) -> None:
        """Raises RunError unless ``config_index`` is a known start configuration of the run's
        task (the scenario is read once per scenario and process)."""
        scenario = entry.config.scenario
        with self._lock:
            n_known = self._known_configs.get(scenario)
        if n_known is None:
            n_known = len(load_scenario(scenario).robot.start_configs)
            with self._lock:
                self._known_configs[scenario] = n_known
        if not 0 <= config_index < n_known:
            raise RunError(f"start configuration {config_index}: the task has known ones 0-{n_known - 1}")

    # -- what the page asks -------------------------------------------------------------------
    def status(self, run: int, entry: RunEntry, index: int, params: np.ndarray, config_index: int) -> dict:
        """What is known of point ``(run, index)``: its per-world results and its rendering from
        known start configuration ``config_index`` (None until computed), and its job."""
        self.check_config(entry, config_index)
        folder = self.folder(entry, index)
        worlds = self.cached_worlds(folder, params)
        video = self.cached_video(folder, params, config_index)
        if video is not None:
            video = {**video, "urls": [self.url(folder / f) for f in video["files"]]}
        with self._lock:
            job = self._jobs.get((run, index, config_index))
            job_doc = job.document() if job else None
        return {"run": run, "index": index, "config_index": config_index, "worlds": worlds, "video": video, "job": job_doc}

    def start(self, run: int, entry: RunEntry, index: int, params: np.ndarray, config_index: int) -> dict:
        """Queues the rollout and rendering of the point unless both are on disk or under way;
        raises ServerBusy when the point has a job for another start configuration under way
        (409) or ``MAX_WAITING_JOBS`` jobs wait (429)."""
        doc = self.status(run, entry, index, params, config_index)
        if doc["worlds"] is not None and doc["video"] is not None:
            return doc
        key = (run, index, config_index)
        with self._lock:
            if key not in self._jobs or self._jobs[key].state not in ACTIVE:
                self._refuse_more(run, index)
                self._jobs[key] = Job(entry, index, np.asarray(params, np.float64), config_index)
                self._queue.put(self._jobs[key])
            if self._worker is None:
                self._worker = threading.Thread(target=self._work, name="mjxskill-explore-rollouts", daemon=True)
                self._worker.start()
        return self.status(run, entry, index, params, config_index)

    def _refuse_more(self, run: int, index: int) -> None:
        """Raises ServerBusy when point ``(run, index)`` has a job under way or the queue is full
        (called with the lock held)."""
        for (job_run, job_index, job_config), job in self._jobs.items():
            if (job_run, job_index) == (run, index) and job.state in ACTIVE:
                raise ServerBusy(f"run {run}, evaluation {index} is already being rolled out (known start configuration "
                                 f"{job_config}); ask again when it is done", status=409)
        waiting = sum(job.state == "queued" for job in self._jobs.values())
        if waiting >= MAX_WAITING_JOBS:
            raise ServerBusy(f"the rollout queue is full ({waiting} points waiting, at most {MAX_WAITING_JOBS}); "
                             "ask again when one is done", status=429)

    def close(self) -> None:
        """The explorer's end: the worker takes no further job and every rollout built is closed
        (the native engine's worker processes). A job under way is not waited for."""
        with self._lock:
            rollouts, self._rollouts = list(self._rollouts.values()), {}
            self._closed = True
            if self._worker is not None:
                self._queue.put(None)  # the worker ends after the job it runs
        for rollout in rollouts:
            rollout.close()

    # -- the worker ---------------------------------------------------------------------------
    def _set(self, job: Job, stage: str, fraction: float) -> None:
        with self._lock:
            job.stage, job.fraction = stage, fraction

    def _work(self) -> None:
        while True:
            job = self._queue.get()
            if job is None:  # closed
                return
            with self._lock:
                job.state, job.stage, job.started = "running", "starting", time.monotonic()
            try:
                message = self._run(job)
                state = "done"
            except UserError as err:  # a scenario that no longer matches the run, a bad start configuration
                message, state = str(err), "failed"
            except Exception as err:  # noqa: BLE001  (shown on the page; the server keeps serving)
                message, state = f"{type(err).__name__}: {err}", "failed"
            with self._lock:
                job.state, job.message = state, message
                job.fraction = 1.0 if state == "done" else job.fraction

    def _rollout(self, job: Job) -> Rollout:
        config = job.entry.config
        key = (config.scenario, config.goal, config.episode_seconds, config.engine)
        with self._lock:
            rollout = self._rollouts.get(key)
        if rollout is None:
            self._set(job, "loading the scenario and building the rollout", 0.02)
            rollout = self.rollout_factory(job.entry)
            with self._lock:
                if self._closed:  # the explorer ended while this one was built
                    rollout.close()
                    raise RuntimeError("the explorer was closed")
                self._rollouts[key] = rollout
        return rollout

    def _run(self, job: Job) -> str:
        folder = self.folder(job.entry, job.index)
        rollout = self._rollout(job)
        if self.cached_worlds(folder, job.params) is None:
            _write_json(job.entry.run.path, folder / "worlds.json", self._worlds(job, rollout))
        if self.cached_video(folder, job.params, job.config_index) is None:
            return self._render(job, rollout, folder)
        return ""

    def _worlds(self, job: Job, rollout: Rollout) -> dict:
        worlds, names, known = evaluation_worlds(rollout, self.per_config, self.seed)
        self._set(job, f"rolling out {len(names) * self.per_config} worlds ({self.per_config} per start configuration; "
                       "the first call compiles: a minute or two on a CPU)", 0.1)
        out = rollout.run_worlds(job.params[None], worlds)
        success = np.asarray(out.success, bool)[0]
        metric = lambda name: np.asarray(out.metrics[name], np.float64)[0]  # noqa: E731
        force, error = metric("peak_contact_force"), metric("position_error")
        configs = []
        for c, name in enumerate(names):
            rows = slice(c * self.per_config, (c + 1) * self.per_config)
            configs.append({"name": name, "known": bool(known[c]), "success_rate": float(success[rows].mean()),
                            "worlds": [{"success": bool(s), "peak_contact_force": number(f), "position_error": number(e)}
                                       for s, f, e in zip(success[rows], force[rows], error[rows])]})
        return {"format": FORMAT, "params": numbers(job.params), "per_config": self.per_config, "seed": self.seed,
                "episode_seconds": job.entry.config.episode_seconds, "success_rate": float(success.mean()),
                "peak_contact_force": number(np.nanmean(force)) if np.isfinite(force).any() else None,
                "configs": configs}

    def _render(self, job: Job, rollout: Rollout, folder: Path) -> str:
        n_known = len(rollout.scenario.robot.start_configs)
        if not 0 <= job.config_index < n_known:
            raise RunError(f"start configuration {job.config_index}: the task has known ones 0-{n_known - 1}")
        if self._no_video is not None:
            return f"the per-world results are ready; no video: {self._no_video}"
        fmt = "mp4" if shutil.which("ffmpeg") else "png"
        out = folder / f"known-{job.config_index}"
        self._set(job, "tracing the episode (compiled once)", 0.55)
        world = render_world(rollout, job.config_index, self.seed)
        progress = lambda i, n: self._set(job, f"rendering frame {i} of {n}", 0.6 + 0.4 * i / n)  # noqa: E731
        try:
            paths = render_episode(rollout, job.params, world, out, fmt, *self.size, progress=progress, root=job.entry.run.path)
        except RenderUnavailable as err:
            self._no_video = err.reason
            return f"the per-world results are ready; no video: {err.reason}"
        _write_json(job.entry.run.path, folder / f"known-{job.config_index}.json", {
            "format": FORMAT, "params": numbers(job.params), "seed": self.seed, "size": list(self.size), "kind": fmt,
            "fps": float(rollout.scenario.bt_hz),
            "world": f"known start configuration {job.config_index}, objects randomized with seed {self.seed}",
            "files": [Path(os.path.relpath(p, folder)).as_posix() for p in paths]})
        return ""
