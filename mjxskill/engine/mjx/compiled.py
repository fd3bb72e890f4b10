"""``compile_rollout``: every parameter set in every randomized world in one compiled call.

    rollout = compile_rollout(load_scenario("push"), worlds=7)   # plans the scenario's goal
    out = rollout(params, key)       # params (B, P) in rollout.parameter_names order
    out.objectives                   # (B, O), larger is better, mean over the W worlds
    out.success                      # (B, W) bool
    out.metrics                      # name -> (B, W) per-world values

The B x W episodes are flattened into one batch axis and mapped with the backend's batching
strategy (``mjxskill.engine.mjx.batching``); the same key gives the same worlds and bit-identical
outputs. Worlds are drawn independently for every (parameter set, world) pair, as the paper
draws them per evaluation.

The jitted functions are closures over what they need (the episode spec, the MJX model and
data template, the world sampler), built once here, Brax style: nothing mutable is passed to
``jax.jit`` as a static argument.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from mjxskill._runtime import enable_compilation_cache
from mjxskill.bt_compiled import compile_tree
from mjxskill.engine.common.arrays import JAX
from mjxskill.engine.common.rewards import build_terms
from mjxskill.engine.common.types import EpisodeResult, EpisodeSetup, RolloutOutput, episode_setup, objective_matrix, summarize
from mjxskill.engine.common.worlds import Worlds, WorldSampler, make_sampler, sample_worlds, worlds_per_config
from mjxskill.engine.mjx.batching import STRATEGIES, default_strategy, over_worlds
from mjxskill.engine.mjx.episode import EpisodeSpec, run_episode
from mjxskill.engine.mjx.leaves import build_leaf_programs
from mjxskill.engine.mjx.program_cache import Program, load_or_trace
from mjxskill.engine.mjx.sharding import shard_batch
from mjxskill.engine.protocol import RolloutBase
from mjxskill.errors import quote
from mjxskill.scenario.schema import Scenario
from mjxskill.sim.model import build_model
from mjxskill.task import PlannedTask, plan_task


# On the CPU a call runs at most this many episodes (whole parameter sets; more when one set has
# more worlds): with jax 0.10.2 a call of 6 x 60 push episodes never returns, every XLA thread
# parked, with or without the YNN-fusion and multi-threaded-Eigen flags, where 2 x 60 and 6 x 20
# return (benchmarks/NOTES.md section 13). Wider calls buy no speed on a few cores.
CPU_EPISODES_PER_CALL = 120


@dataclass(frozen=True, eq=False)
class MJXRollout(RolloutBase):
    """A compiled rollout of one planned task and W worlds per parameter set: the ``Rollout`` of
    ``mjxskill.engine.protocol`` (see the module doc). episode_spec: the traced episode's static
    description (tree, leaf programs, reward terms, ``setup``). The callables are the jitted
    closures ``compile_rollout`` built; ``program`` picks the batched-episode program per shape.
    """

    scenario: Scenario
    task: PlannedTask
    worlds: int
    episode_spec: EpisodeSpec
    sampler: WorldSampler
    mj_model: mujoco.MjModel
    strategy: str
    chunk: int | None
    _sample: Callable = field(repr=False)  # (key, batch) -> Worlds (batch, W)
    _episodes: Callable = field(repr=False)  # (params (B, P), worlds (B, W)) -> RolloutOutput, unjitted
    _trace: Callable = field(repr=False)  # jitted (params (P,), world) -> (EpisodeResult, TickRecord)
    _programs: dict = field(default_factory=dict, repr=False)

    PARAMS_DTYPE = np.float32  # MJX simulates in float32

    @property
    def setup(self) -> EpisodeSetup:
        return self.episode_spec.setup

    def __call__(self, params, key: jax.Array) -> RolloutOutput:
        """Rolls out (B, P) ``params`` in W worlds each, drawn from ``key``."""
        params = self.check_params(params)
        # Sampling is a separate small program, so a call and ``run_worlds`` share one compile.
        return self._run(params, self.sample_worlds(key, len(params)))

    def run_worlds(self, params, worlds: Worlds) -> RolloutOutput:
        """Rolls out (B, P) ``params`` in explicit ``worlds`` of leading shape (B, W') or (W',)
        (the same worlds for every parameter set)."""
        params = self.check_params(params)
        lead = worlds.config_index.shape
        if len(lead) == 1:
            worlds = jax.tree.map(lambda x: jnp.broadcast_to(x, (len(params),) + x.shape), worlds)
        elif len(lead) != 2 or lead[0] != len(params):
            raise ValueError(f"worlds must have leading shape (W,) or ({len(params)}, W), got {lead}")
        return self._run(params, worlds)

    def _run(self, params: np.ndarray | jax.Array, worlds: Worlds) -> RolloutOutput:
        params = jnp.asarray(params)
        b, w = worlds.config_index.shape
        per_call = max(1, CPU_EPISODES_PER_CALL // w)
        if jax.default_backend() != "cpu" or b <= per_call:
            return self.program(params, worlds).fn(params, worlds)
        # Calls of per_call sets, the last padded with copies of the last set so that every
        # call runs the one program; the padding's results are dropped.
        pad = -b % per_call
        take = lambda x: jnp.concatenate([x, jnp.repeat(x[-1:], pad, axis=0)]) if pad else x  # noqa: E731
        params, worlds = take(params), jax.tree.map(take, worlds)
        parts = [self._run(params[i:i + per_call], jax.tree.map(lambda x: x[i:i + per_call], worlds))
                 for i in range(0, b + pad, per_call)]
        return jax.tree.map(lambda *xs: jnp.concatenate(xs)[:b], *parts)

    def program(self, params, worlds: Worlds) -> Program:
        """The batched-episode program for arguments shaped like (B, P) ``params`` and (B, W)
        ``worlds``: on one device read from (or traced into) the on-disk program cache, so that
        another process skips the tracing (``mjxskill.engine.mjx.program_cache``); over several
        devices the sharded ``jax.jit`` program, traced in each process."""
        shapes = tuple((np.shape(x), str(x.dtype)) for x in jax.tree.leaves((params, worlds)))
        if shapes not in self._programs:
            if jax.local_device_count() > 1:
                self._programs[shapes] = Program(jax.jit(self._episodes), "jit", "")
            else:
                self._programs[shapes] = load_or_trace(self.identity(), self.mj_model, self._episodes, params, worlds)
        return self._programs[shapes]

    def identity(self) -> str:
        """Everything besides the model and the argument shapes that shapes the program (part
        of its cache key): the scenario's validated content, the plan, the episode settings."""
        setup = self.setup
        return repr((self.scenario, self.task, setup.ticks, setup.steps_per_tick, self.strategy, self.chunk))

    def trace(self, params, world: Worlds):
        """Per-tick record of one parameter vector (P,) in one world (unbatched fields):
        (EpisodeResult, TickRecord with leading (T,)); for inspection and rendering."""
        params = self.check_params(params)[0]
        return self._trace(jnp.asarray(params), world)

    def sample_worlds(self, key: jax.Array, batch: int) -> Worlds:
        """The (batch, W) worlds ``rollout(params, key)`` uses for ``batch`` parameter sets."""
        return self._sample(key, batch)

    def close(self) -> None:
        """Nothing to release: XLA frees the programs and buffers with the rollout."""

    def worlds_per_config(self, key: jax.Array, per_config: int, configs: np.ndarray | None = None) -> Worlds:
        """``per_config`` worlds from each start configuration (default: the training ones;
        pass ``scenario.robot.eval_configs`` for the unseen ones)."""
        sampler = self.sampler if configs is None else self.sampler._replace(configs=np.asarray(configs, np.float32))
        return worlds_per_config(sampler, key, per_config)


def compile_rollout(
    scn: Scenario,
    task: PlannedTask | None = None,
    *,
    worlds: int | None = None,
    episode_seconds: float | None = None,
    batching: str | None = None,
    chunk: int | None = None,
    start_configs: np.ndarray | None = None,
    mj_model: mujoco.MjModel | None = None,
) -> MJXRollout:
    """Builds the rollout of ``task`` in ``scn`` (compiled lazily on the first call per batch size).

    task: a ``mjxskill.task.PlannedTask`` (default: ``plan_task(scn)``, the scenario's goal).
    worlds: W, randomized worlds per parameter set (default: the scenario's n_worlds).
    episode_seconds: overrides the scenario's episode length.
    batching: "vmap", "map" or "chunked" (default: the backend's fastest, see ``engine.mjx.batching``).
    start_configs: (C, 7) start configurations to draw from (default: the training ones).
    mj_model: the model to simulate (default: ``mjxskill.build_model(scn)``, the MJCF with the world
    model's physics).
    """
    enable_compilation_cache()
    if task is None:
        task = plan_task(scn)
    worlds, seconds, strategy = _checked_settings(scn, worlds, episode_seconds, batching)
    if mj_model is None:
        mj_model = build_model(scn)
    spec = _episode_spec(scn, task, mj_model, seconds)
    model, template = _device_model(mj_model)
    sampler = make_sampler(scn, spec.setup.bindings, start_configs)

    sample = jax.jit(lambda key, batch: sample_worlds(sampler, key, (batch, worlds)), static_argnums=1)
    trace = jax.jit(lambda params, world: run_episode(spec, model, template, params, world, record=True))
    return MJXRollout(
        scenario=scn,
        task=task,
        worlds=worlds,
        episode_spec=spec,
        sampler=sampler,
        mj_model=mj_model,
        strategy=strategy,
        chunk=chunk,
        _sample=sample,
        _episodes=_batched_episodes_fn(scn, spec, model, template, strategy, chunk),
        _trace=trace,
    )


def _checked_settings(scn: Scenario, worlds: int | None, episode_seconds: float | None, batching: str | None):
    """(W, episode seconds, batching strategy) from ``compile_rollout``'s arguments and the
    scenario's defaults; ValueError for a bad one."""
    worlds = scn.randomization.n_worlds if worlds is None else int(worlds)
    if worlds < 1:
        raise ValueError(f"worlds must be >= 1, got {worlds}")
    seconds = scn.episode_seconds if episode_seconds is None else float(episode_seconds)
    if not (seconds > 0 and math.isfinite(seconds)):
        raise ValueError(f"episode_seconds must be positive, got {episode_seconds}")
    strategy = default_strategy() if batching is None else batching
    if strategy not in STRATEGIES:
        raise ValueError(f"unknown batching strategy {quote(strategy)}; expected one of {STRATEGIES}")
    return worlds, seconds, strategy


def _episode_spec(scn: Scenario, task: PlannedTask, mj_model: mujoco.MjModel, seconds: float) -> EpisodeSpec:
    """The traced episode's static description: the compiled tree, its leaf programs, the reward
    terms and the engine-independent setup."""
    setup = episode_setup(scn, task, mj_model, seconds)
    ct = compile_tree(task.tree)
    terms = build_terms(scn, setup.bindings.slot_of, JAX)
    return EpisodeSpec(
        ct=ct,
        leaves=build_leaf_programs(ct, task.parameter_names, setup.bindings, scn.robot.default_stiffness, 1.0 / scn.bt_hz),
        terms=terms,
        setup=setup,
    )


def _device_model(mj_model: mujoco.MjModel) -> tuple[mjx.Model, mjx.Data]:
    """The MJX model and a data template (kinematics computed) on this process's first device.

    MJX places the model on jax.devices()[0] unless told: under jax.distributed that is process
    0's device, which the other processes cannot use; this process's first device is."""
    data = mujoco.MjData(mj_model)
    mujoco.mj_forward(mj_model, data)
    device = jax.local_devices()[0]
    return mjx.put_model(mj_model, device=device), mjx.put_data(mj_model, data, device=device)


def _batched_episodes_fn(scn: Scenario, spec: EpisodeSpec, model: mjx.Model, template: mjx.Data, strategy: str,
                         chunk: int | None) -> Callable:
    """The unjitted (params (B, P), worlds (B, W)) -> RolloutOutput: the B x W episodes as one
    flat batch, mapped with ``strategy`` and split over the local devices, then summarized."""
    weights = objective_matrix(spec.terms, len(scn.objective_names))
    reward_names = tuple(t.name for t in spec.terms)

    def episode(params, world):
        return run_episode(spec, model, template, params, world)

    def batched_episodes(params: jax.Array, worlds_: Worlds) -> RolloutOutput:
        b, w = worlds_.config_index.shape
        flat_params = jnp.repeat(params, w, axis=0)
        flat_worlds = jax.tree.map(lambda x: x.reshape((b * w,) + x.shape[2:]), worlds_)
        # The flat B x W batch is split over all local devices (one device: unchanged).
        res: EpisodeResult = shard_batch(over_worlds(episode, strategy, chunk))(flat_params, flat_worlds)
        res = jax.tree.map(lambda x: x.reshape((b, w) + x.shape[1:]), res)
        return summarize(res, worlds_.config_index, weights, reward_names, xp=jnp)

    return batched_episodes
