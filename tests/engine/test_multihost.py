"""Beyond one machine: docs/engines.md's multi-host example run as two local processes with
``jax.distributed`` (CPU, gloo), each evaluating half of a batch; the gathered objectives equal
what one process computes for the same halves, bit for bit. And batches that fill a large device
are accepted by both engines."""

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np

from mjxskill import compile_rollout, load_scenario, plan_task
from mjxskill.engine.native import NativeRollout

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "examples" / "multihost.py"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_two_processes_gather_what_one_process_computes(tmp_path):
    out = tmp_path / "gathered.json"
    args = ["--sets", "2", "--worlds", "2", "--episode-seconds", "0.3", "--seed", "5"]
    # An empty cache: each process traces its own program, as on a fresh cluster (a warm cache
    # hid that MJX put every process's model on process 0's device).
    env = dict(os.environ, MJXSKILL_CACHE_DIR=str(tmp_path / "cache"))
    done = subprocess.run([sys.executable, str(EXAMPLE), "--local", "2", "--coordinator", f"127.0.0.1:{_free_port()}",
                           *args, "--json", str(out)], capture_output=True, text=True, timeout=900, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    gathered = json.loads(out.read_text())

    # One process, the same halves with the same keys (as docs/engines.md's snippet splits them).
    rollout = compile_rollout(load_scenario("push"), worlds=2, episode_seconds=0.3)
    lo, hi = rollout.bounds
    params = np.random.default_rng(5).uniform(lo, hi, size=(2, len(lo)))
    key = jax.random.key(5)
    halves = [rollout(part, jax.random.fold_in(key, i)) for i, part in enumerate(np.array_split(params, 2))]
    objectives = np.concatenate([np.asarray(h.objectives) for h in halves])
    success = np.concatenate([np.asarray(h.success).mean(axis=1) for h in halves])
    np.testing.assert_array_equal(np.asarray(gathered["objectives"], np.float32), objectives)
    np.testing.assert_array_equal(gathered["success_rate"], success)


def test_batches_that_fill_a_large_device_are_accepted():
    # 32 parameter sets x 64 worlds = 2048 episodes per call: the native engine runs them (a
    # few control steps each), the compiled rollout lowers its program for that shape.
    scn = load_scenario("push")
    task = plan_task(scn)
    params = np.tile(task.defaults, (32, 1))
    native = NativeRollout(scn, task, worlds=64, episode_seconds=0.1)
    out = native(params, jax.random.key(0))
    assert out.objectives.shape == (32, 2) and out.success.shape == (32, 64)
    assert np.all(np.isfinite(out.objectives))
    rollout = compile_rollout(scn, task, worlds=64, episode_seconds=0.1)
    worlds = rollout.sample_worlds(jax.random.key(0), 32)
    p = jax.numpy.asarray(params, jax.numpy.float32)
    lowered = rollout.program(p, worlds).fn.lower(p, worlds)
    assert "2048" in lowered.as_text()  # the flat batch of episodes
