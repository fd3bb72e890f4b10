"""One batch of parameter sets evaluated by several processes with ``jax.distributed``.

On a cluster, start one process per host with the same ``--coordinator`` and ``--processes``
and its own ``--process-id``; on one machine, ``--local`` starts them all here (CPU):

    python docs/examples/multihost.py --local 2                 # two local processes
    python docs/examples/multihost.py --coordinator 10.0.0.1:47611 --processes 4 --process-id 0

Each process rolls out its share of the (B, P) parameter sets on its own devices, with worlds
from its own key, and the objectives are gathered so that every process holds all (B, O). Keep
B divisible by the process count so that every process compiles the same batch shape (one
compile, shared through the persistent cache on a shared file system). With ``--json``,
process 0 writes the gathered objectives and success rates.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path


def wait_for_all(name: str, minutes: float = 60.0) -> None:
    """A barrier of the coordination service (no collective): the processes' compiles and
    rollouts take different times, and the gloo collectives below give up on a peer that is more
    than 30 s late. JAX's own checkpointing waits the same way (its client is not public API)."""
    from jax._src import distributed

    client = distributed.global_state.client
    if client is not None:
        client.wait_at_barrier(name, timeout_in_ms=int(minutes * 60_000))


def evaluate(args) -> None:
    import mjxskill  # noqa: F401  (XLA flags first)
    import jax
    import numpy as np
    from jax.experimental import multihost_utils

    # CPU processes exchange arrays through gloo (the setting only concerns the CPU backend; it is
    # set before anything starts a backend, as jax.distributed.initialize requires)
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=args.coordinator, num_processes=args.processes,
                               process_id=args.process_id)
    rollout = mjxskill.compile_rollout(mjxskill.load_scenario(args.task), worlds=args.worlds,
                                       episode_seconds=args.episode_seconds)
    lo, hi = rollout.bounds
    params = np.random.default_rng(args.seed).uniform(lo, hi, size=(args.sets, len(lo)))   # the batch: (B, P)
    key = jax.random.key(args.seed)
    mine = np.array_split(params, jax.process_count())[jax.process_index()]              # this process's share
    out = rollout(mine, jax.random.fold_in(key, jax.process_index()))                     # local devices only
    wait_for_all("rollouts done")
    objectives = multihost_utils.process_allgather(out.objectives, tiled=True)           # (B, O) everywhere
    success = multihost_utils.process_allgather(out.success.mean(axis=1), tiled=True)    # (B,)
    if jax.process_index() == 0 and args.json:
        Path(args.json).write_text(json.dumps({"objectives": np.asarray(objectives).tolist(),
                                               "success_rate": np.asarray(success).tolist()}))
    print(f"process {jax.process_index()}/{jax.process_count()}: {len(mine)} of {len(params)} parameter sets; "
          f"gathered objectives {np.asarray(objectives).shape}", flush=True)


def wait_all_or_stop(procs: list[subprocess.Popen]) -> int:
    """The worst exit code of the local processes; once one fails, the others are stopped (they
    would wait for it at the next barrier until its timeout)."""
    while True:
        codes = [p.poll() for p in procs]
        if any(c not in (None, 0) for c in codes) or all(c == 0 for c in codes):
            break
        time.sleep(0.5)
    for p in procs:
        if p.poll() is None:
            p.terminate()
    return max(abs(p.wait()) for p in procs)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--local", type=int, metavar="N", help="start N processes on this machine")
    parser.add_argument("--coordinator", default="127.0.0.1:47611", help="host:port of process 0")
    parser.add_argument("--processes", type=int, default=1)
    parser.add_argument("--process-id", type=int, default=0)
    parser.add_argument("--task", default="push")
    parser.add_argument("--sets", type=int, default=6, help="parameter sets B (divisible by the process count)")
    parser.add_argument("--worlds", type=int, default=7)
    parser.add_argument("--episode-seconds", type=float, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="process 0 writes the gathered results here")
    args = parser.parse_args(argv)
    if args.local:
        base = [sys.executable, __file__, "--coordinator", args.coordinator, "--processes", str(args.local),
                "--task", args.task, "--sets", str(args.sets), "--worlds", str(args.worlds), "--seed", str(args.seed)]
        base += ["--episode-seconds", str(args.episode_seconds)] if args.episode_seconds else []
        base += ["--json", args.json] if args.json else []
        procs = [subprocess.Popen(base + ["--process-id", str(i)], env=dict(os.environ)) for i in range(args.local)]
        return wait_all_or_stop(procs)
    evaluate(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
