"""The native engine on a Ray cluster: a local two-node cluster on loopback (head and
one node, 1 CPU each, no dashboard, a small object store).

- the library: ``RayRollout`` around a ``NativeRollout``, on the cluster ``connect_cluster``
  connected, gives the results one process gives, bit for bit, and a call during which one of
  its actors is killed finishes with those same results;
- must-hold 1: ``train ... --engine native --ray-address ADDRESS`` writes the evaluations.csv of
  the same run without Ray, and its header says ``ray: 2 nodes``;
- must-hold 3: ``experiment push --repeats 2 ... --ray-address ADDRESS`` runs its two repetitions
  at the same time (one actor each; their wall-clock intervals in state.json overlap) and its
  report's figures are those of the same experiment without Ray;
- an address where no cluster answers is one ``error:`` line naming it, exit 2, nothing written.

Skipped where Ray is not installed (``pip install -e '.[ray]'``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import ray  # noqa: E402  (the test extra's)
import ray.cluster_utils as cluster_utils  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
NODE = dict(num_cpus=1, object_store_memory=80 * 1024 * 1024, node_ip_address="127.0.0.1")


@pytest.fixture(scope="module")
def cluster():
    """A head and one more node on loopback; the workers import this checkout's mjxskill."""
    saved = {k: os.environ.get(k) for k in ("PYTHONPATH", "RAY_USAGE_STATS_ENABLED")}
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), saved["PYTHONPATH"]]))
    os.environ["RAY_USAGE_STATS_ENABLED"] = "0"
    local = cluster_utils.Cluster(initialize_head=True, head_node_args=dict(NODE, include_dashboard=False))
    local.add_node(**NODE)
    local.wait_for_nodes()
    try:
        yield local
    finally:
        if ray.is_initialized():
            ray.shutdown()
        local.shutdown()
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def _params(task, n: int, seed: int = 0) -> np.ndarray:
    lower, upper = np.asarray(task.bounds)
    return lower + (upper - lower) * np.random.default_rng(seed).random((n, len(lower)))


def _same(a, b) -> None:
    np.testing.assert_array_equal(a.objectives, b.objectives)
    np.testing.assert_array_equal(a.success, b.success)
    for name in a.metrics:
        np.testing.assert_array_equal(a.metrics[name], b.metrics[name], err_msg=name)


def test_cluster_results_are_one_process_results_even_when_an_actor_dies(cluster, push_task):
    from mjxskill.engine.build import connect_cluster
    from mjxskill.engine.native import NativeRollout, RayRollout
    import jax

    scn, task = push_task
    params = _params(task, 6)
    with NativeRollout(scn, task, worlds=2, episode_seconds=1.0) as local:
        worlds = local.sample_worlds(jax.random.key(3), len(params))
        expected = local.run_worlds(params, worlds)
    info = connect_cluster(cluster.address)
    with RayRollout(NativeRollout(scn, task, worlds=2, episode_seconds=1.0), info) as remote:
        assert (remote.cluster.nodes, remote.cluster.cpus) == (2, 2)
        pool = remote.start()
        assert len(pool.actors) == 2
        _same(remote.run_worlds(params, worlds), expected)

        # a call during which one actor is killed: its slice runs again on the other one
        victim, got = pool.actors[0], {}
        call = threading.Thread(target=lambda: got.update(out=remote.run_worlds(params, worlds)))
        pool.submitted.clear()
        call.start()
        assert pool.submitted.wait(timeout=60)
        ray.kill(victim, no_restart=True)
        call.join(timeout=300)
        assert "out" in got, "the call did not finish"
        assert pool.retried >= 1 and victim not in pool.actors
        _same(got["out"], expected)
        _same(remote.run_worlds(params, worlds), expected)  # and the next call too


def _train(tmp: Path, name: str, *extra: str, command: str = "mjxskill.train") -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    args = ["push", "--budget", "12", "--batch-size", "6", "--init", "6", "--worlds", "2", "--episode-seconds", "1",
            "--seed", "0", "--engine", "native", "--quiet", "--out", str(tmp / name), *extra]
    return subprocess.run([sys.executable, "-m", command, *args], cwd=tmp, env=env, capture_output=True,
                          text=True, timeout=900)


def test_train_on_the_cluster_writes_the_evaluations_of_a_local_run(cluster, tmp_path):
    on_ray = _train(tmp_path, "ray", "--ray-address", cluster.address)
    assert on_ray.returncode == 0, on_ray.stderr[-3000:]
    assert "ray: 2 nodes, 2 CPUs" in on_ray.stdout and "on 2 actors" in on_ray.stdout
    local = _train(tmp_path, "local")
    assert local.returncode == 0, local.stderr[-3000:]
    assert (tmp_path / "ray" / "evaluations.csv").read_bytes() == (tmp_path / "local" / "evaluations.csv").read_bytes()
    assert "cluster: ray" in (tmp_path / "ray" / "config.yaml").read_text()
    assert cluster.address not in (tmp_path / "ray" / "config.yaml").read_text()
    assert "cluster: null" in (tmp_path / "local" / "config.yaml").read_text()


QUICK_GP = ["n_raw=64", "n_restarts=2", "n_opt_steps=10", "fit_starts=1", "fit_steps=10"]  # tests/cli/test_train.py's (cli_helpers.QUICK_GP)
EXPERIMENT = ["--repeats", "2", "--worlds", "1", "--budget", "4", "--batch-size", "2", "--init", "2", "--per-config", "1", "--random", "1",
              "--validation-per-config", "1", "--protocol", "paper", "--confirm-per-config", "0",
              *(a for option in QUICK_GP for a in ("--optimizer-option", option))]
RUN_FILES = ("evaluations.csv", "evaluation/evaluation.json", "evaluation/validation.json")


def test_an_experiment_on_the_cluster_runs_its_repetitions_at_once_with_the_figures_of_a_local_one(cluster, tmp_path):
    on_ray = _train(tmp_path, "ray", *EXPERIMENT, "--ray-address", cluster.address, command="mjxskill.experiment")
    assert on_ray.returncode == 0, on_ray.stderr[-3000:]
    assert "ray: 2 nodes, 2 CPUs" in on_ray.stdout and "2 repetitions at a time, each on 1 actor" in on_ray.stdout
    local = _train(tmp_path, "local", *EXPERIMENT, command="mjxskill.experiment")
    assert local.returncode == 0, local.stderr[-3000:]

    state = json.loads((tmp_path / "ray" / "state.json").read_text())
    (a,), (b,) = state["repetitions"]["seed-0"], state["repetitions"]["seed-1"]
    assert max(a["started"], b["started"]) < min(a["ended"], b["ended"]), state["repetitions"]  # at the same time
    assert state["sessions"][-1]["ray"] == {"nodes": 2, "cpus": 2, "repetitions_at_a_time": 2}
    (c,), (d,) = json.loads((tmp_path / "local" / "state.json").read_text())["repetitions"].values()
    assert c["ended"] <= d["started"]  # one after the other

    reports = [json.loads((tmp_path / name / "report.json").read_text()) for name in ("ray", "local")]
    assert (reports[0]["protocol"].pop("cluster"), reports[1]["protocol"].pop("cluster")) == ("ray", None)
    for report in reports:  # the wall times and sessions differ, and only they (and where it ran)
        del report["wall_time"], report["sessions"]
    assert reports[0]["status"] == {"repetitions_done": 2, "repetitions": 2}
    assert reports[0] == reports[1]
    for kind in ("optimizer", "random_search"):
        for seed in (0, 1):
            for name in RUN_FILES if kind == "optimizer" else RUN_FILES[:1]:
                path = Path(kind, f"seed-{seed}", name)
                assert (tmp_path / "ray" / path).read_bytes() == (tmp_path / "local" / path).read_bytes(), path


def test_an_unreachable_cluster_is_one_error_line_and_nothing_written(tmp_path):
    with __import__("socket").socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        address = f"127.0.0.1:{s.getsockname()[1]}"
    for command in ("mjxskill.train", "mjxskill.experiment"):
        done = _train(tmp_path, "run", "--ray-address", address, command=command)
        assert done.returncode == 2
        errors = [line for line in done.stderr.splitlines() if "error:" in line]
        assert len(errors) == 1 and address in errors[0] and errors[0].startswith(command), done.stderr
        assert not (tmp_path / "run").exists()
        assert not done.stdout
