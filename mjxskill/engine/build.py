"""The two physics engines behind one interface, and which one a run uses.

``mjx``: the compiled rollout (``mjxskill.engine.mjx``): every episode of a call in one XLA program;
what accelerators are for. ``native``: the native MuJoCo engine (``mjxskill.engine.native``): episodes
in lockstep in numpy over C MuJoCo, one worker process per core; on a CPU it runs the training
workload several times faster than MJX does (benchmarks/throughput.py, results in
benchmarks/RESULTS.md), and the two agree on success rates (benchmarks/agreement.py).
``auto`` picks MJX on a GPU or TPU and the native engine on a CPU.

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


def build_rollout(scn: Scenario, task: PlannedTask, engine: str, *, worlds: int | None = None,
                  episode_seconds: float | None = None, start_configs: np.ndarray | None = None,
                  mj_model: mujoco.MjModel | None = None, workers: int | None = None, cluster: str | None = None,
                  actors: int | None = None) -> Rollout:
    """The rollout of ``task`` in ``scn`` on ``engine`` ("mjx" or "native"; resolve "auto" first).
    ``cluster``: a Ray cluster's address ("auto" or HOST:PORT) the native engine's episodes run
    on (``mjxskill.engine.native.ray_pool``), on ``actors`` actors (default one per CPU); MJX on many hosts is ``jax.distributed``'s
    (docs/engines.md, "Scaling"), so the MJX engine refuses it."""
    if engine == "mjx" and cluster is not None:
        raise ClusterError("a Ray cluster runs the native engine's episodes; MJX across hosts is jax.distributed's "
                           "(docs/engines.md, Scaling): use --engine native with --ray-address")
    if engine == "mjx":
        # lazy, as the native engine below: a run imports only the engine it runs (MJX ~2 s more than jax)
        from mjxskill.engine.mjx.compiled import compile_rollout

        return compile_rollout(scn, task, worlds=worlds, episode_seconds=episode_seconds,
                               start_configs=start_configs, mj_model=mj_model)
    if engine == "native":
        from mjxskill.engine.native.rollout import NativeRollout  # lazy: a run imports only the engine it runs

        return NativeRollout(scn, task, worlds=worlds, episode_seconds=episode_seconds,
                             start_configs=start_configs, mj_model=mj_model, workers=workers, cluster=cluster,
                             actors=actors)
    raise ValueError(f"unknown engine {quote(engine)}; expected one of {', '.join(ENGINES)}")
