"""The native MuJoCo engine in one process: the episodes of a planned task on native MuJoCo,
numpy and the reference BT interpreter, without MJX.

``NativeRollout`` runs all episodes of a call on one MuJoCo batch with the compiled law as its
control callback (``mjxskill.engine.native.batched``), in this process. Parallelism is a wrapper around it that
satisfies the same ``Rollout``: ``ProcessPoolRollout`` (``mjxskill.engine.native.pool``: worker
processes on this machine) and ``RayRollout`` (``mjxskill.engine.native.ray_pool``: the actors of a
Ray cluster); both rebuild this engine from a recipe (``engine_from_recipe``) where the episodes
run, and ``build_rollout`` (``mjxskill.engine.build``) composes them. ``run_episode`` is one
episode in a plain Python loop, one control step at a time (what ``trace`` records); the
references the tests and benchmarks check this engine against are
``mjxskill.engine.native_reference``'s. Same MJCF model and timestep as the compiled rollout,
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
from pathlib import Path
from typing import Callable, Protocol

import jax
import mujoco
import numpy as np

from mjxskill.bt_compiled import compile_tree
from mjxskill.engine.native.batched import run_batched
from mjxskill.engine.native.callback import data_offsets
from mjxskill.engine.native.episode import NativeEpisode
from mjxskill.sim.model import build_model
from mjxskill.scenario import load_scenario
from mjxskill.errors import ScenarioError
from mjxskill.scenario.schema import Scenario
from mjxskill.task import PlannedTask, plan_task
from mjxskill.engine.native.leaves import build_native_leaves
from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.bindings import nominal_poses
from mjxskill.engine.common.rewards import build_terms
from mjxskill.engine.common.types import EpisodeResult, EpisodeSetup, RolloutOutput, episode_setup, objective_matrix, summarize
from mjxskill.engine.protocol import RolloutBase
from mjxskill.engine.common.worlds import Worlds, make_sampler, sample_worlds, worlds_per_config

# (params (N, P), worlds of leading shape (N,)) -> the N episodes' results, in order
EpisodeRunner = Callable[[np.ndarray, Worlds], list[EpisodeResult]]


def engine_from_recipe(spec: dict, model: bytes) -> "NativeRollout":
    """The engine of a recipe (``mjxskill.engine.native.pool.recipe``) and MJB bytes, in this
    process: what a worker process or a Ray actor runs its slices on. RuntimeError
    if the scenario's files are not those the recipe was made from."""
    source = Path(spec["scenario"])
    scn = load_scenario(source)
    if sources_sha256(scn) != spec["sha256"]:
        raise RuntimeError(f"{source} or a skill library it includes changed since the engine was built; build it again")
    configs = spec["start_configs"]
    return NativeRollout(scn, plan_task(scn, spec["goal"]), worlds=spec["worlds"],
                         episode_seconds=spec["episode_seconds"],
                         start_configs=None if configs is None else np.asarray(configs),
                         mj_model=mujoco.MjModel.from_binary_path("model.mjb", {"model.mjb": model}))


def sources_sha256(scn: Scenario) -> str:
    """sha256 over the bytes of the scenario file and of the skill libraries it includes."""
    digest = hashlib.sha256()
    for path in (scn.source, *scn.libraries):
        digest.update(hashlib.sha256(Path(path).read_bytes()).digest())
    return digest.hexdigest()


class NativeRollout(RolloutBase):
    """The episodes of ``task`` in ``scn`` on native MuJoCo, in this process (arguments as
    ``compile_rollout``; nothing is compiled). ``threads``: the threads that step a call's batch
    (1; ``benchmarks/throughput.py`` measures more); ``timing``: a dict that a call adds its
    seconds in ``Batch.step`` to under "physics_s" (None: not measured). Results depend on
    neither."""

    scenario: Scenario
    task: PlannedTask
    setup: EpisodeSetup

    def __init__(self, scn: Scenario, task: PlannedTask | None = None, *, worlds: int | None = None, episode_seconds: float | None = None,
                 start_configs: np.ndarray | None = None, mj_model: mujoco.MjModel | None = None):
        if task is None:
            task = plan_task(scn)
        if mj_model is None:
            mj_model = build_model(scn)
        seconds = scn.episode_seconds if episode_seconds is None else float(episode_seconds)
        self.scenario, self.task = scn, task
        self.start_configs = None if start_configs is None else np.asarray(start_configs)
        self.threads = 1
        self.timing: dict | None = None
        # The scenario and skill library files as this engine read them: workers rebuild from
        # them and check they are unchanged.
        self.scenario_sha256 = sources_sha256(scn)
        self.setup = episode_setup(scn, task, mj_model, seconds)
        self.worlds = scn.randomization.n_worlds if worlds is None else int(worlds)
        self.sampler = make_sampler(scn, self.setup.bindings, start_configs)
        sampler, n_worlds = self.sampler, self.worlds
        # The compiled rollout's sampling program, written the same way: the same worlds, bit for bit.
        self._sample = jax.jit(lambda key, batch: sample_worlds(sampler, key, (batch, n_worlds)), static_argnums=1)
        if mj_model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
            raise ScenarioError(f"{scn.scene}: option integrator RK4: the native engine runs its impedance law as "
                                "MuJoCo's control callback, once a step, and RK4 calls it four times a step; use "
                                "Euler, implicit or implicitfast, or the MJX engine (--engine mjx)")
        self.mj_model = mj_model
        self.data_offsets = data_offsets(mj_model)  # where the control callback reads an mjData's fields
        self.base_pair_friction = mj_model.pair_friction.copy()
        self.tree = task.tree
        # the tree's tables for a batch's tick over rows (batched.BatchEpisodes); a tree the compiled
        # tick cannot run (a Parallel of more than 31 children) is refused here, as MJX refuses it
        self.compiled_tree = compile_tree(self.tree)
        self.leaf_ids = self.compiled_tree.leaf_ids.tolist()  # pre-order, the order of the programs below
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
    def run_episode(self, params, world: Worlds, record: bool = False, on_step=None):
        """Rolls out ``params`` (P,) in ``world`` (unbatched numpy fields) in a plain Python loop,
        one control step at a time; the result's fields are numpy scalars / (R,) as in
        ``rollout.types.EpisodeResult``. With ``record``, returns (result, TickRecord of numpy
        arrays with a leading (T,) axis) like the compiled rollout's ``trace`` (T: ticks run;
        fewer if the world diverged). ``on_step(data, tau)``: called after every control step
        (``NativeEpisode.plain_steps``)."""
        episode = NativeEpisode(self, params, world, self.mj_model, record=record)
        episode.run(on_step)
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

    def run_worlds(self, params, worlds: Worlds) -> RolloutOutput:
        """Rolls out (B, P) ``params`` in ``worlds`` of leading shape (B, W) or (W,) (the same
        worlds for every parameter set): the B x W episodes on one MuJoCo batch with the compiled
        law. Returns a RolloutOutput of numpy arrays with the compiled rollout's fields and
        metric names."""
        return self.gather(params, worlds, self.run_episodes)

    def run_episodes(self, params: np.ndarray, worlds: Worlds) -> list[EpisodeResult]:
        """The results of the episodes ``params`` (N, P) in ``worlds`` (leading shape (N,)), in
        order: what a wrapper runs elsewhere (a worker process, a Ray actor) on a slice."""
        return run_batched(self, params, worlds, threads=self.threads, timing=self.timing)

    def gather(self, params, worlds: Worlds, run: EpisodeRunner) -> RolloutOutput:
        """``run_worlds`` with the episodes run by ``run`` (this engine's ``run_episodes``, a
        wrapper's, or a reference's): (B, P) ``params`` in ``worlds`` of leading shape (B, W) or
        (W,), flattened to B x W episodes and summarized as the compiled rollout does."""
        params = self.check_params(params)
        worlds = jax.tree.map(np.asarray, worlds)
        if worlds.config_index.ndim == 1:
            worlds = jax.tree.map(lambda x: np.broadcast_to(x, (len(params),) + x.shape), worlds)
        if worlds.config_index.ndim != 2 or worlds.config_index.shape[0] != len(params):
            raise ValueError(f"worlds must have leading shape (W,) or ({len(params)}, W), got {worlds.config_index.shape}")
        b, w = worlds.config_index.shape
        flat_params = np.repeat(params, w, axis=0)
        flat_worlds = jax.tree.map(lambda x: np.ascontiguousarray(x.reshape((b * w,) + x.shape[2:])), worlds)
        results = run(flat_params, flat_worlds)
        res = EpisodeResult(*(np.array([getattr(r, f) for r in results]).reshape((b, w) + np.shape(getattr(results[0], f)))
                              for f in EpisodeResult._fields))
        return summarize(res, worlds.config_index, self.objective_matrix, self.reward_names, xp=np)

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
        """Nothing to release: the episodes ran in this process (``Rollout.close``)."""


class EpisodePool(Protocol):
    """Where a wrapper's episodes run: ``run`` (params (N, P), worlds (N,)) -> the N results in
    order, as ``NativeRollout.run_episodes``; ``close`` stops it (``WorkerPool``, ``RayPool``)."""

    def run(self, params: np.ndarray, worlds: Worlds) -> list[EpisodeResult]: ...

    def close(self) -> None: ...


def episode_slices(n_episodes: int, n_slices: int) -> list[np.ndarray]:
    """The episode indices each of ``n_slices`` workers runs, in round-robin order (episode i in
    slice i mod n), the empty slices left out: a call's episodes are its parameter sets' worlds in
    turn, and the sets' physics differ (one that misses the object steps a third faster), so
    contiguous slices left one worker waiting for the other (benchmarks/NOTES.md section 33)."""
    return [part for part in (np.arange(k, n_episodes, n_slices) for k in range(max(1, n_slices))) if len(part)]


def in_order(parts: list[np.ndarray], results: list[list]) -> list:
    """Every slice's results (``results[k]`` for the episodes ``parts[k]``) back in episode order."""
    out: list = [None] * sum(len(part) for part in parts)
    for part, got in zip(parts, results):
        for i, r in zip(part, got):
            out[i] = r
    return out


class PooledRollout(RolloutBase):
    """A ``Rollout`` around a one-process ``NativeRollout`` (``inner``, as Brax wraps an env)
    whose calls' episodes run on a pool elsewhere: ``ProcessPoolRollout``
    (``mjxskill.engine.native.pool``) and ``RayRollout`` (``mjxskill.engine.native.ray_pool``).
    What a caller reads, the worlds a key gives and ``trace`` are ``inner``'s; the pool
    (``make_pool``) starts with the first call that needs it, or ``start``, and ``close`` stops
    it. Episodes are deterministic and never interact, so the results are ``inner``'s bit for bit."""

    def __init__(self, inner: NativeRollout):
        self.inner = inner
        self._pool: EpisodePool | None = None

    @property
    def scenario(self) -> Scenario:
        return self.inner.scenario

    @property
    def task(self) -> PlannedTask:
        return self.inner.task

    @property
    def setup(self) -> EpisodeSetup:
        return self.inner.setup

    @property
    def worlds(self) -> int:
        return self.inner.worlds

    @property
    def mj_model(self) -> mujoco.MjModel:
        return self.inner.mj_model

    def sample_worlds(self, key, batch: int) -> Worlds:
        return self.inner.sample_worlds(key, batch)

    def worlds_per_config(self, key, per_config: int, configs: np.ndarray | None = None) -> Worlds:
        return self.inner.worlds_per_config(key, per_config, configs)

    def trace(self, params, world: Worlds):
        return self.inner.trace(params, world)

    def __call__(self, params, key) -> RolloutOutput:
        params = self.check_params(params)
        return self.run_worlds(params, self.sample_worlds(key, len(params)))

    def run_worlds(self, params, worlds: Worlds) -> RolloutOutput:
        """As ``NativeRollout.run_worlds``, the episodes run by ``run_episodes``."""
        return self.inner.gather(params, worlds, self.run_episodes)

    def run_episodes(self, params: np.ndarray, worlds: Worlds) -> list[EpisodeResult]:
        return self.start().run(params, worlds)

    def make_pool(self) -> EpisodePool:
        raise NotImplementedError

    def start(self) -> EpisodePool:
        """Starts the pool now (a call starts it when it first needs it: a few seconds of
        imports per worker or actor). Returns it."""
        if self._pool is None:
            self._pool = self.make_pool()
        return self._pool

    def close(self) -> None:
        """Stops the pool (it also stops when this process exits); twice is harmless."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None
