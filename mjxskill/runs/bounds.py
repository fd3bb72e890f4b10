"""Upper bounds of the evaluation's numbers (``evaluate``, ``experiment``, ``explore`` and
``experiment.yaml``), far beyond any use, for the reason the run settings have theirs
(``mjxskill.scenario.schema``): a typo must be refused before anything is written, not exhaust
the machine (``evaluate --random 10**9`` was a MemoryError traceback). Imports nothing: the
commands' parsers read it before mujoco may be imported.

Beside the fixed bounds, the sizes that take memory are checked against the machine's
available memory (``/proc/meminfo``'s MemAvailable): the native engine's worker processes
(``--workers``) and the episodes of one call (batch x worlds, or an evaluation's candidates x
worlds x start configurations), whatever command makes the call. The per-worker and per-episode
numbers were measured on the project's machine (x86-64, 2 cores, 24 GB; mujoco 4.0.0, jax
0.10.2) with the push scenario, by a script that read a worker's VmRSS from /proc/PID/status
after a call of 6 sets x 2 worlds with --workers 2 (357.4 and 357.1 MiB), and the peak RSS
(getrusage ru_maxrss) of one call of N episodes in one process after a warm-up call.
"""

import os

MAX_PER_CONFIG = 1000  # evaluation or validation worlds per start configuration; the paper's evaluation has 5
MAX_RANDOM_SETS = 10_000  # random parameter sets of an evaluation; the paper has 10
MAX_VALIDATION_CANDIDATES = 100  # solutions the pick's validation rolls out again; default 3
# The episodes of one call, every command's (train: batch x worlds; evaluate and the pick's
# validation: candidates x worlds x start configurations), all held in memory at once (64 x 4096).
MAX_CALL_EPISODES = 262_144
MAX_WORKERS = 256  # a fixed bound beside the memory's: more processes than any machine has cores
# Measured (see above): the resident memory of one native worker process after a call
# (357 MiB: Python, numpy, jax, mujoco and the engine's model), rounded up.
WORKER_BYTES = 360 * 2**20
# Measured (see above): memory per episode of a call, native engine in one process: peak RSS
# 399.5 MiB for a call of 64 episodes, 458.4 MiB for 2048 ((458.4 - 399.5) MiB / 1984 = 30 KiB an
# episode). MJX's peak was its compilation's (1.3 GiB for a call of 32 episodes, none higher for 256),
# so no per-episode number of its own could be told apart: the native one bounds both.
EPISODE_BYTES = 31 * 2**10


def available_memory() -> int | None:
    """Bytes of memory the machine can give without swapping (MemAvailable), None if unknown."""
    try:
        with open("/proc/meminfo", "rb") as fh:  # a kernel file: never a FIFO
            for line in fh.read(1 << 16).decode("ascii", "replace").splitlines():
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def gib(n: float) -> str:
    return f"{n / 2**30:.1f} GiB"


def workers_problem(workers: int, available: int | None = None) -> str | None:
    """Why ``workers`` native worker processes cannot run here (None: they can): more than
    ``MAX_WORKERS``, or more memory than the machine has available, with the numbers."""
    if workers > MAX_WORKERS:
        return f"must be at most {MAX_WORKERS}, got {workers}"
    available = available_memory() if available is None else available
    need = workers * WORKER_BYTES
    if available is not None and need > available:
        return (f"{workers} workers need about {gib(need)} ({WORKER_BYTES // 2**20} MiB each, measured), more than the "
                f"{gib(available)} this machine has available; at most {max(1, available // WORKER_BYTES)} fit")
    return None


def call_episodes_problem(episodes: int, how: str, available: int | None = None) -> str | None:
    """Why one call of ``episodes`` episodes cannot run here (None: it can): more than
    ``MAX_CALL_EPISODES``, or more memory than is available. ``how`` says what makes them
    (e.g. "batches of 64 x 100 worlds"); the message has the numbers."""
    if episodes > MAX_CALL_EPISODES:
        return f"{how} make {episodes} episodes per call, more than {MAX_CALL_EPISODES}"
    available = available_memory() if available is None else available
    need = episodes * EPISODE_BYTES
    if available is not None and need > available:
        return (f"{how} make {episodes} episodes per call, which need about {gib(need)} "
                f"({EPISODE_BYTES // 2**10} KiB each, measured), more than the {gib(available)} this machine has available")
    return None

__all__ = ["EPISODE_BYTES", "MAX_CALL_EPISODES", "MAX_PER_CONFIG", "MAX_RANDOM_SETS", "MAX_VALIDATION_CANDIDATES", "MAX_WORKERS",
           "WORKER_BYTES", "available_memory", "call_episodes_problem", "workers_problem"]
