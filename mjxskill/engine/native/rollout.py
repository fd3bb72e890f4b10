"""The native MuJoCo engine: the episodes of a planned task on native MuJoCo, numpy and the
reference BT interpreter, without MJX.

Three ways of stepping the same episodes (``mjxskill.engine.native.episode``): ``run_episode``, a
plain single-process Python loop one control step at a time (how a user without this project
would write it: the baseline the benchmarks measure against, and the reference in tests); the
numpy lockstep (``mjxskill.engine.native.lockstep``: one vectorized numpy law per control step for
all episodes, the reference of the compiled law); and the engine's own, ``run_worlds`` and
``__call__``: all episodes of a call on MuJoCo batches with the compiled law
(``mjxskill.engine.native.batched``), split over ``workers`` processes
(``mjxskill.engine.native.pool``) or over the actors of a Ray cluster (``cluster``,
``mjxskill.engine.native.ray_pool``), each batch stepped by ``threads`` threads. Same MJCF model and timestep as the compiled rollout,
same worlds (``mjxskill.engine.common.worlds``), same world-model poses for the skills, same
divergence containment (``mjxskill.engine.common.types``); float64 throughout where MJX runs float32.
Nothing of the compiled rollout or of MJX is imported: this engine is the independent reference
the compiled one is tested against.

    native = NativeRollout(scn, task, worlds=7)           # as compile_rollout(scn, task, worlds=7)
    out = native(params, key)                             # as a compiled rollout: RolloutOutput
    out = native.run_worlds(params, native.sample_worlds(key, len(params)))
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import jax
import mujoco
import numpy as np

from mjxskill.ebt.interpreter import Interpreter
from mjxskill.engine.native.batched import run_batched
from mjxskill.engine.native.episode import NativeEpisode
from mjxskill.engine.native.lockstep import run_lockstep
from mjxskill.engine.native.pool import WorkerPool
from mjxskill.engine.native.ray_pool import RayPool, connect
from mjxskill.errors import quote
from mjxskill.sim.model import build_model
from mjxskill.scenario import load_scenario
from mjxskill.scenario.schema import Scenario
from mjxskill.task import PlannedTask, plan_task
from mjxskill.engine.native.leaves import build_native_leaves
from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.bindings import nominal_poses
from mjxskill.engine.common.rewards import build_terms
from mjxskill.engine.common.types import EpisodeResult, EpisodeSetup, RolloutOutput, episode_setup, objective_matrix, summarize
from mjxskill.engine.protocol import RolloutBase
from mjxskill.engine.common.worlds import Worlds, make_sampler, sample_worlds, worlds_per_config


STEPPINGS = ("batch", "lockstep", "plain")


def engine_from_recipe(spec: dict, model: bytes) -> "NativeRollout":
    """The engine of a recipe (``mjxskill.engine.native.pool.recipe``) and MJB bytes, in this
    process (workers=1): what a worker process or a Ray actor runs its slices on. RuntimeError
    if the scenario's files are not those the recipe was made from."""
    source = Path(spec["scenario"])
    scn = load_scenario(source)
    if sources_sha256(scn) != spec["sha256"]:
        raise RuntimeError(f"{source} or a skill library it includes changed since the engine was built; build it again")
    configs = spec["start_configs"]
    return NativeRollout(scn, plan_task(scn, spec["goal"]), worlds=spec["worlds"],
                         episode_seconds=spec["episode_seconds"],
                         start_configs=None if configs is None else np.asarray(configs),
                         mj_model=mujoco.MjModel.from_binary_path("model.mjb", {"model.mjb": model}), workers=1)


def sources_sha256(scn: Scenario) -> str:
    """sha256 over the bytes of the scenario file and of the skill libraries it includes."""
    digest = hashlib.sha256()
    for path in (scn.source, *scn.libraries):
        digest.update(hashlib.sha256(Path(path).read_bytes()).digest())
    return digest.hexdigest()


def default_workers() -> int:
    """One worker process per core this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


class NativeRollout(RolloutBase):
    """The episodes of ``task`` in ``scn`` on native MuJoCo (arguments as ``compile_rollout``;
    nothing is compiled). workers: processes ``run_worlds`` splits a call's episodes over
    (default: one per core; 1 runs them in this process); threads: the threads that step the
    batch of a call run in this process (workers == 1). cluster: the address of a Ray cluster
    ("auto" or HOST:PORT) whose CPUs run the calls' episodes instead of local workers (one actor
    per CPU, or ``actors``: an experiment's repetitions that run at the same time share the
    cluster's CPUs; ``pip install 'mjxskill[ray]'``); connected at once, ClusterError if it
    cannot be. Results depend on none of these."""

    scenario: Scenario
    task: PlannedTask
    setup: EpisodeSetup

    def __init__(self, scn: Scenario, task: PlannedTask | None = None, *, worlds: int | None = None, episode_seconds: float | None = None,
                 start_configs: np.ndarray | None = None, mj_model: mujoco.MjModel | None = None,
                 workers: int | None = None, threads: int = 1, cluster: str | None = None,
                 actors: int | None = None):
        if task is None:
            task = plan_task(scn)
        if mj_model is None:
            mj_model = build_model(scn)
        seconds = scn.episode_seconds if episode_seconds is None else float(episode_seconds)
        self.scenario, self.task = scn, task
        self.start_configs = None if start_configs is None else np.asarray(start_configs)
        self.workers = default_workers() if workers is None else max(1, int(workers))
        self.threads = max(1, int(threads))
        # a dict that a call in this process (workers == 1) adds its seconds in Batch.step to
        # under "physics_s" (benchmarks/throughput.py); None: not measured
        self.timing: dict | None = None
        self._pool = None
        self.actors = None if actors is None else max(1, int(actors))  # Ray actors (None: one per CPU of the cluster)
        self.cluster = None  # the ClusterInfo of the Ray cluster the calls run on
        if cluster is not None:
            self.cluster = connect(cluster)
        # The scenario and skill library files as this engine read them: workers rebuild from
        # them and check they are unchanged.
        self.scenario_sha256 = sources_sha256(scn)
        self.setup = episode_setup(scn, task, mj_model, seconds)
        self.worlds = scn.randomization.n_worlds if worlds is None else int(worlds)
        self.sampler = make_sampler(scn, self.setup.bindings, start_configs)
        sampler, n_worlds = self.sampler, self.worlds
        # The compiled rollout's sampling program, written the same way: the same worlds, bit for bit.
        self._sample = jax.jit(lambda key, batch: sample_worlds(sampler, key, (batch, n_worlds)), static_argnums=1)
        self.mj_model = mj_model
        self.base_pair_friction = mj_model.pair_friction.copy()
        self.tree = task.tree
        self.leaf_ids = [i for i, n in enumerate(Interpreter(self.tree).nodes) if n.is_leaf]
        self.leaf_position = {nid: k for k, nid in enumerate(self.leaf_ids)}
        nominal_pos, nominal_quat = nominal_poses(self.setup.bindings)
        self.programs = build_native_leaves(
            self.tree.leaves(), task.parameter_names, self.setup.bindings.slot_of, nominal_pos, nominal_quat, 1.0 / scn.bt_hz
        )
        self.terms = build_terms(scn, self.setup.bindings.slot_of, HOST)
        self.objective_matrix = objective_matrix(self.terms, len(scn.objective_names), np.float64)

    def sample_worlds(self, key, batch: int) -> Worlds:
        """The (batch, W) worlds for ``batch`` parameter sets drawn from ``key``: the same as
        the compiled rollout's for the same key, settings and worlds (one shared sampler)."""
        return jax.tree.map(np.asarray, self._sample(key, batch))

    def worlds_per_config(self, key, per_config: int, configs: np.ndarray | None = None) -> Worlds:
        """``per_config`` worlds from each start configuration (as ``Rollout.worlds_per_config``)."""
        sampler = self.sampler if configs is None else self.sampler._replace(configs=np.asarray(configs, np.float32))
        return jax.tree.map(np.asarray, worlds_per_config(sampler, key, per_config))

    # -- episodes ---------------------------------------------------------------------------
    def run_episode(self, params, world: Worlds, record: bool = False):
        """Rolls out ``params`` (P,) in ``world`` (unbatched numpy fields) in a plain Python loop,
        one control step at a time; the result's fields are numpy scalars / (R,) as in
        ``rollout.types.EpisodeResult``. With ``record``, returns (result, TickRecord of numpy
        arrays with a leading (T,) axis) like the compiled rollout's ``trace`` (T: ticks run;
        fewer if the world diverged)."""
        episode = NativeEpisode(self, params, world, self.mj_model, record=record)
        for t in range(self.setup.ticks):
            episode.begin_tick()
            episode.plain_steps()
            if not episode.end_tick(t):
                break
        return (episode.result(), episode.trace()) if record else episode.result()

    def trace(self, params, world: Worlds):
        """Per-tick record of one parameter vector (P,) in one world, as ``Rollout.trace``."""
        params = np.asarray(params, float).reshape(-1)
        return self.run_episode(params, jax.tree.map(np.asarray, world), record=True)

    def __call__(self, params, key) -> RolloutOutput:
        """Rolls out (B, P) ``params`` in W worlds each, drawn from ``key`` (the compiled
        rollout's worlds for the same key)."""
        params = self.check_params(params)
        return self.run_worlds(params, self.sample_worlds(key, len(params)))

    def run_worlds(self, params, worlds: Worlds, *, stepping: str = "batch") -> RolloutOutput:
        """Rolls out (B, P) ``params`` in ``worlds`` of leading shape (B, W) or (W,) (the same
        worlds for every parameter set). ``stepping``: "batch", the engine's own way (the B x W
        episodes on MuJoCo batches with the compiled law, split over the worker processes);
        "lockstep", the numpy law for all episodes at once (the law's reference); "plain", one
        episode after another in the plain loop (the baseline). The last two run in this
        process. Returns a RolloutOutput of numpy arrays with the compiled rollout's fields and
        metric names."""
        if stepping not in STEPPINGS:
            raise ValueError(f"stepping must be one of {', '.join(STEPPINGS)}, got {quote(stepping)}")
        params = self.check_params(params)
        worlds = jax.tree.map(np.asarray, worlds)
        if worlds.config_index.ndim == 1:
            worlds = jax.tree.map(lambda x: np.broadcast_to(x, (len(params),) + x.shape), worlds)
        if worlds.config_index.ndim != 2 or worlds.config_index.shape[0] != len(params):
            raise ValueError(f"worlds must have leading shape (W,) or ({len(params)}, W), got {worlds.config_index.shape}")
        b, w = worlds.config_index.shape
        flat_params = np.repeat(params, w, axis=0)
        flat_worlds = jax.tree.map(lambda x: np.ascontiguousarray(x.reshape((b * w,) + x.shape[2:])), worlds)
        if stepping == "plain":
            results = [self.run_episode(flat_params[i], jax.tree.map(lambda x: x[i], flat_worlds)) for i in range(b * w)]
        elif stepping == "lockstep":
            results = run_lockstep(self, flat_params, flat_worlds)
        else:
            results = self._run_batched(flat_params, flat_worlds)
        res = EpisodeResult(*(np.array([getattr(r, f) for r in results]).reshape((b, w) + np.shape(getattr(results[0], f)))
                              for f in EpisodeResult._fields))
        return summarize(res, worlds.config_index, self.objective_matrix, self.reward_names, xp=np)

    def _run_batched(self, params: np.ndarray, worlds: Worlds) -> list[EpisodeResult]:
        if self.cluster is None and min(self.workers, len(params)) <= 1:
            return run_batched(self, params, worlds, threads=self.threads, timing=self.timing)
        return self.start_workers().run(params, worlds)

    def start_workers(self):
        """Starts the worker processes (or the Ray actors) now (a call starts them when it first
        needs them: a few seconds of imports each). Returns the pool."""
        if self._pool is None and self.cluster is not None:
            self._pool = RayPool(self, self.cluster.address, build=engine_from_recipe, actors=self.actors)
        elif self._pool is None and self.workers > 1:
            self._pool = WorkerPool(self, self.workers)
        return self._pool

    def memory_per_episode(self) -> int:
        """Bytes one episode holds while it runs: its model copy and its MjData (buffer and the
        arena it used), measured on a short plain episode."""
        world = jax.tree.map(lambda x: np.asarray(x)[0, 0], self.sample_worlds(jax.random.key(0), 1))
        episode = NativeEpisode(self, self.task.defaults, world, self.mj_model.__copy__())
        for t in range(min(self.setup.ticks, 5)):
            episode.begin_tick()
            episode.plain_steps()
            episode.end_tick(t)
        return int(mujoco.mj_sizeModel(episode.model) + episode.data.nbuffer + episode.data.maxuse_arena)

    def close(self) -> None:
        """Stops the worker processes or the Ray actors (they also stop when this process exits)."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None
