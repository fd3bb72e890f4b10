"""The two physics engines behind one interface, and which one a run uses.

``mjx``: the compiled rollout (``mjxskill.engine.mjx``): every episode of a call in one XLA program;
what accelerators are for. ``native``: the native MuJoCo engine (``mjxskill.engine.native``): a
call's episodes on MuJoCo batches, one worker process per core (``ProcessPoolRollout``) or the
actors of a Ray cluster (``RayRollout``) around the one-process ``NativeRollout``; on a CPU it
runs the training workload several times faster than MJX does (benchmarks/throughput.py,
results in benchmarks/RESULTS.md), and the two agree on success rates (benchmarks/agreement.py).
``auto`` picks MJX on a GPU or TPU and the native engine on a CPU (``resolve_engine``, once, where
a run's configuration is made); ``connect_cluster`` connects a Ray cluster once, and its handle
goes to ``build_rollout``.

Both engines give ``rollout(params (B, P), key) -> RolloutOutput`` with the same worlds for the
same key, ``run_worlds``, ``sample_worlds``, ``worlds_per_config``, ``trace``,
``parameter_names``, ``bounds``, ``task``, ``scenario``, ``mj_model``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mjxskill.errors import ClusterError, quote

if TYPE_CHECKING:  # pragma: no cover
    import mujoco
    import numpy as np

    from mjxskill.engine.native.ray_pool import ClusterInfo
    from mjxskill.engine.protocol import Rollout
    from mjxskill.scenario.schema import Scenario
    from mjxskill.task import PlannedTask

ENGINES = ("mjx", "native")
CHOICES = (*ENGINES, "auto")


def resolve_engine(name: str, backend: str | None = None) -> tuple[str, str]:
    """(engine, why) for ``name`` in CHOICES; ``backend`` defaults to jax's default backend."""
    if name in ENGINES:
        return name, "as asked"
    if name != "auto":
        raise ValueError(f"unknown engine {quote(name)}; expected one of {', '.join(CHOICES)}")
    if backend is None:
        import jax  # lazy: ~1 s, and train/evaluate/experiment --help and bad input import this module

        backend = jax.default_backend()
    if backend in ("gpu", "cuda", "rocm", "tpu"):
        return "mjx", f"auto: MJX on the {backend.upper()}"
    return "native", f"auto: the native engine on the {backend.upper()} (faster than MJX there, benchmarks/RESULTS.md)"


def connect_cluster(address: str | None, engine: str = "native") -> ClusterInfo | None:
    """The Ray cluster at ``address`` ("auto" or HOST:PORT) that ``engine``'s episodes are to run
    on, connected now and once (None: no address, this machine); its handle goes to
    ``build_rollout``. Only the native engine runs on a cluster (MJX on many hosts is
    ``jax.distributed``'s, docs/engines.md, "Scaling"). ClusterError (naming the address) for
    another engine, a cluster that cannot be reached, or Ray not installed."""
    if address is None:
        return None
    if engine != "native":
        raise ClusterError(f"a Ray cluster (--ray-address) runs the native engine's episodes; this run's engine is "
                           f"{engine} (MJX across hosts is jax.distributed's: docs/engines.md, Scaling)")
    from mjxskill.engine.native.ray_pool import connect  # lazy: Ray is an optional extra, connected on demand

    return connect(address)


def build_rollout(scn: Scenario, task: PlannedTask, engine: str, *, worlds: int | None = None,
                  episode_seconds: float | None = None, start_configs: np.ndarray | None = None,
                  mj_model: mujoco.MjModel | None = None, workers: int | None = None,
                  cluster: ClusterInfo | None = None, actors: int | None = None) -> Rollout:
    """The rollout of ``task`` in ``scn`` on ``engine`` ("mjx" or "native"; resolve "auto" first).
    The native engine is the one-process ``NativeRollout`` wrapped by where its episodes run:
    ``RayRollout`` on ``cluster`` (the handle of ``connect_cluster``) on ``actors`` actors
    (default one per CPU), else ``ProcessPoolRollout`` over ``workers`` processes (default one per
    core; 1: this process alone). Results depend on none of these."""
    if engine == "mjx":
        if cluster is not None:
            raise ValueError("cluster: only the native engine runs on a Ray cluster (connect_cluster refuses MJX)")
        # lazy, as the native engine below: a run imports only the engine it runs (MJX ~2 s more than jax)
        from mjxskill.engine.mjx.compiled import compile_rollout

        return compile_rollout(scn, task, worlds=worlds, episode_seconds=episode_seconds,
                               start_configs=start_configs, mj_model=mj_model)
    if engine == "native":
        from mjxskill.engine.native import pool, ray_pool, rollout  # lazy: a run imports only the engine it runs

        inner = rollout.NativeRollout(scn, task, worlds=worlds, episode_seconds=episode_seconds,
                                      start_configs=start_configs, mj_model=mj_model)
        if cluster is not None:
            return ray_pool.RayRollout(inner, cluster, actors)
        workers = pool.default_workers() if workers is None else max(1, int(workers))
        return pool.ProcessPoolRollout(inner, workers) if workers > 1 else inner
    raise ValueError(f"unknown engine {quote(engine)}; expected one of {', '.join(ENGINES)}")
