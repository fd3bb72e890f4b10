"""The native engine's worker processes: ``ProcessPoolRollout``, a ``Rollout`` around the
one-process ``NativeRollout`` whose calls' episodes are split over one process per core.

A native episode is single-threaded Python and C, so a 2-core machine runs two at once only in
two processes. Each worker (``python -m mjxskill.engine.native.worker``, a fresh interpreter: nothing
inherited from a parent that has started JAX's threads, and no re-import of the user's main
script as ``multiprocessing``'s spawn would do) rebuilds the engine once from a recipe: the
scenario file and its skill libraries (checked by their sha256), the goal, the settings and the MuJoCo model (MJB
bytes in a frame of their own: no temporary file, so a killed pool leaves nothing on disk). It
then runs its slice of the episodes (``rollout.episode_slices``: round-robin) on one MuJoCo batch
(``NativeRollout.run_episodes``).
Episodes are deterministic and never interact, so the results equal one process's bit for bit
(tests/engine/native/test_engine.py).

The messages are data only: length-prefixed frames holding JSON or NPZ (no pickle). Workers
ignore SIGINT; Ctrl-C reaches the parent, which stops them. A worker whose parent has gone sees
its input close and exits.
"""

from __future__ import annotations

import io
import json
import os
import struct
import subprocess
import sys
import weakref
from pathlib import Path

import mujoco
import numpy as np

from mjxskill.engine.common.types import EpisodeResult
from mjxskill.engine.common.worlds import Worlds
from mjxskill.engine.native.rollout import NativeRollout, PooledRollout, episode_slices, in_order


# -- framing (both sides) -----------------------------------------------------------------------
def write_frame(stream, kind: bytes, payload: bytes) -> None:
    stream.write(kind + struct.pack("<Q", len(payload)) + payload)
    stream.flush()


def read_frame(stream) -> tuple[bytes, bytes]:
    head = stream.read(9)
    if len(head) < 9:
        raise EOFError("the other side closed the pipe")
    kind, (size,) = head[:1], struct.unpack("<Q", head[1:])
    payload = stream.read(size)
    if len(payload) < size:
        raise EOFError("the other side closed the pipe mid-message")
    return kind, payload


def pack_arrays(**arrays) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def unpack_arrays(payload: bytes) -> dict:
    with np.load(io.BytesIO(payload), allow_pickle=False) as npz:
        return {name: npz[name] for name in npz.files}


# -- the parent's side --------------------------------------------------------------------------
def default_workers() -> int:
    """One worker process per core this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def recipe(engine: NativeRollout) -> dict:
    """What a worker needs to rebuild ``engine`` (a ``NativeRollout``), as JSON data."""
    source = Path(engine.scenario.source)
    configs = engine.start_configs
    return {
        "scenario": str(source),
        "sha256": engine.scenario_sha256,
        "goal": engine.task.goal,
        "worlds": engine.worlds,
        "episode_seconds": engine.episode_seconds,
        "start_configs": None if configs is None else np.asarray(configs, float).tolist(),
    }


def model_bytes(mj_model) -> bytes:
    """``mj_model`` as MJB bytes (what ``mujoco.mj_saveModel`` writes to a file)."""
    buffer = np.zeros(mujoco.mj_sizeModel(mj_model), np.uint8)
    mujoco.mj_saveModel(mj_model, None, buffer)
    return buffer.tobytes()


def _stop_workers(procs: list) -> None:
    """Kills and reaps the workers still running, closes their pipes."""
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        for stream in (proc.stdin, proc.stdout):
            try:
                stream.close()
            except OSError:
                pass
    procs.clear()


class WorkerPool:
    """``n`` worker processes for ``engine``; ``run`` splits episodes over them. ``close`` stops
    them; so does the pool's garbage collection or the interpreter's exit, for an engine
    dropped without ``close`` (a finalizer)."""

    def __init__(self, engine: NativeRollout, n: int):
        self.n = n
        self.procs: list[subprocess.Popen] = []
        self._stop = weakref.finalize(self, _stop_workers, self.procs)
        message, model = json.dumps(recipe(engine)).encode(), model_bytes(engine.mj_model)
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
        try:
            for _ in range(n):
                proc = subprocess.Popen([sys.executable, "-m", "mjxskill.engine.native.worker"], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, env=env)
                write_frame(proc.stdin, b"R", message)
                write_frame(proc.stdin, b"M", model)
                self.procs.append(proc)
            for proc in self.procs:
                self._expect(proc, b"K")
        except BaseException:
            self.close()
            raise

    def _expect(self, proc, kind: bytes) -> bytes:
        try:
            got, payload = read_frame(proc.stdout)
        except EOFError:
            raise RuntimeError(f"a native engine worker (pid {proc.pid}) exited with code {proc.wait()}") from None
        if got == b"E":
            raise RuntimeError(f"a native engine worker failed:\n{payload.decode()}")
        if got != kind:
            raise RuntimeError(f"a native engine worker sent {got!r}, expected {kind!r}")
        return payload

    def run(self, params: np.ndarray, worlds) -> list[EpisodeResult]:
        """Results of the episodes params (N, P) in worlds (N,), in order."""
        parts = episode_slices(len(params), self.n)
        try:
            for proc, part in zip(self.procs, parts):
                fields = {f"world_{name}": np.asarray(x)[part] for name, x in zip(worlds._fields, worlds)}
                write_frame(proc.stdin, b"J", pack_arrays(params=params[part], **fields))
            results = []
            for proc, part in zip(self.procs, parts):
                arrays = unpack_arrays(self._expect(proc, b"O"))
                results.append([EpisodeResult(*(arrays[f][i] for f in EpisodeResult._fields)) for i in range(len(part))])
        except BaseException:  # Ctrl-C or a failure: stop the workers now, not after their slices
            self.close()
            raise
        return in_order(parts, results)

    def close(self) -> None:
        self._stop()  # runs _stop_workers once, however often close is called


class ProcessPoolRollout(PooledRollout):
    """``inner``'s episodes (a one-process ``NativeRollout``) split over ``workers`` worker
    processes on this machine (``mjxskill.engine.build.build_rollout``'s default: one per core);
    a call of one episode, or ``workers`` 1, runs in this process. Results are ``inner``'s, bit
    for bit (tests/engine/native/test_engine.py)."""

    def __init__(self, inner: NativeRollout, workers: int):
        super().__init__(inner)
        self.workers = max(1, int(workers))

    def make_pool(self) -> WorkerPool:
        return WorkerPool(self.inner, self.workers)

    def run_episodes(self, params: np.ndarray, worlds: Worlds) -> list[EpisodeResult]:
        if min(self.workers, len(params)) <= 1:
            return self.inner.run_episodes(params, worlds)
        return self.start().run(params, worlds)
