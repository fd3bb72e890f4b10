"""``compile_rollout``: every parameter set in every randomized world in one compiled call.

    rollout = compile_rollout(load_scenario("push"), worlds=7)
    out = rollout(params, key)       # params (B, P) in scn.parameter_names order
    out.objectives                   # (B, O), larger is better, mean over the W worlds
    out.success                      # (B, W) bool
    out.metrics                      # name -> (B, W) per-world values

The B x W episodes are flattened into one batch axis and mapped with the backend's batching
strategy (``mjxskill.sim.batching``); the same key gives the same worlds and bit-identical
outputs. Worlds are drawn independently for every (parameter set, world) pair, as the paper
draws them per evaluation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from mjxskill.bt_compiled import compile_tree
from mjxskill.ebt.nodes import Status
from mjxskill.rollout.bindings import SceneBindings, bind_scene, referenced_objects
from mjxskill.rollout.episode import EpisodeResult, EpisodeSpec, run_episode
from mjxskill.rollout.leaves import build_leaf_programs
from mjxskill.rollout.program_cache import Program, load_or_trace
from mjxskill.rollout.rewards import build_terms, objective_matrix
from mjxskill.rollout.sharding import shard_batch
from mjxskill.rollout.worlds import Worlds, WorldSampler, make_sampler, sample_worlds, worlds_per_config
from mjxskill.scenario_schema import Scenario
from mjxskill.sim.batching import STRATEGIES, default_strategy, over_worlds
from mjxskill.sim.controller import ControllerConfig

DEFAULT_HOLE_HALF_WIDTH = 0.02  # m: a peg tip inside this square around the hole axis is "in"


class RolloutOutput(NamedTuple):
    """objectives (B, O) float32; success (B, W) bool; metrics: name -> (B, W) array
    (``reward_<name>`` totals per world, ``diverged``, ``bt_status``, ``bt_done_tick``,
    ``position_error`` m, ``orientation_error_deg``, ``insertion_depth`` m, ``max_force`` N,
    ``config_index``)."""

    objectives: jax.Array
    success: jax.Array
    metrics: dict


def load_model(scn: Scenario) -> mujoco.MjModel:
    """The scenario's MJCF with its gravity and control period applied."""
    model = mujoco.MjModel.from_xml_path(scn.scene)
    model.opt.timestep = 1.0 / scn.control_hz
    if not scn.gravity:
        model.opt.gravity[:] = 0.0
    return model


def _leaf_objects(tree) -> list[str]:
    return [leaf.args["object"] for leaf in tree.leaves() if leaf.primitive == "set_goal_from_object"]


@dataclass(frozen=True, eq=False)
class Rollout:
    """A compiled rollout for one scenario and W worlds per parameter set (see module doc)."""

    scenario: Scenario
    worlds: int
    spec: EpisodeSpec
    sampler: WorldSampler
    model: mjx.Model
    template: mjx.Data
    strategy: str
    chunk: int | None
    _objective_matrix: np.ndarray = field(repr=False)
    mj_model: mujoco.MjModel | None = field(default=None, repr=False)
    _programs: dict = field(default_factory=dict, repr=False)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return self.scenario.parameter_names

    @property
    def objective_names(self) -> tuple[str, ...]:
        return self.scenario.objective_names

    @property
    def reward_names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.spec.terms)

    @property
    def control_steps_per_episode(self) -> int:
        return self.spec.ticks * self.spec.steps_per_tick

    def check_params(self, params) -> np.ndarray:
        params = np.asarray(params, np.float32)
        if params.ndim == 1:
            params = params[None]
        n = len(self.parameter_names)
        if params.ndim != 2 or params.shape[1] != n:
            raise ValueError(
                f"params must have shape (B, {n}) in the order {list(self.parameter_names)}, got {params.shape}"
            )
        if not np.all(np.isfinite(params)):
            raise ValueError(f"params must be finite, got {params}")
        return params

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

    def _run(self, params: np.ndarray, worlds: Worlds) -> RolloutOutput:
        params = jnp.asarray(params)
        return self.program(params, worlds).fn(params, worlds)

    def program(self, params, worlds: Worlds) -> Program:
        """The batched-episode program for arguments shaped like (B, P) ``params`` and (B, W)
        ``worlds``: on one device read from (or traced into) the on-disk program cache, so that
        another process skips the tracing (``mjxskill.rollout.program_cache``); over several
        devices the sharded ``jax.jit`` program, traced in each process."""
        shapes = tuple((np.shape(x), str(x.dtype)) for x in jax.tree.leaves((params, worlds)))
        if shapes not in self._programs:
            if jax.local_device_count() > 1 or self.mj_model is None:
                self._programs[shapes] = Program(partial(_run_worlds, self), "jit", "")
            else:
                self._programs[shapes] = load_or_trace(self, self.mj_model, partial(_batched_episodes, self), params, worlds)
        return self._programs[shapes]

    def trace(self, params, world: Worlds):
        """Per-tick record of one parameter vector (P,) in one world (unbatched fields):
        (EpisodeResult, TickRecord with leading (T,)); for inspection and rendering."""
        params = self.check_params(params)[0]
        return _trace(self, jnp.asarray(params), world)

    def sample_worlds(self, key: jax.Array, batch: int) -> Worlds:
        """The (batch, W) worlds ``rollout(params, key)`` uses for ``batch`` parameter sets."""
        return _sample(self, key, batch)

    def worlds_per_config(self, key: jax.Array, per_config: int, configs: np.ndarray | None = None) -> Worlds:
        """``per_config`` worlds from each start configuration (default: the training ones;
        pass ``scenario.robot.eval_configs`` for the unseen ones)."""
        sampler = self.sampler if configs is None else self.sampler._replace(configs=np.asarray(configs, np.float32))
        return worlds_per_config(sampler, key, per_config)


def compile_rollout(
    scn: Scenario,
    worlds: int | None = None,
    *,
    episode_seconds: float | None = None,
    batching: str | None = None,
    chunk: int | None = None,
    start_configs: np.ndarray | None = None,
) -> Rollout:
    """Builds the rollout of ``scn`` (compiled lazily on the first call per batch size).

    worlds: W, randomized worlds per parameter set (default: the scenario's n_worlds).
    episode_seconds: overrides the scenario's episode length.
    batching: "vmap", "map" or "chunked" (default: the backend's fastest, see sim.batching).
    start_configs: (C, 7) start configurations to draw from (default: the training ones).
    """
    worlds = scn.randomization.n_worlds if worlds is None else int(worlds)
    if worlds < 1:
        raise ValueError(f"worlds must be >= 1, got {worlds}")
    seconds = scn.episode_seconds if episode_seconds is None else float(episode_seconds)
    if not (seconds > 0 and math.isfinite(seconds)):
        raise ValueError(f"episode_seconds must be positive, got {episode_seconds}")
    strategy = default_strategy() if batching is None else batching
    if strategy not in STRATEGIES:
        raise ValueError(f"unknown batching strategy {strategy!r}; expected one of {STRATEGIES}")

    mj_model = load_model(scn)
    tree = scn.task.tree
    ct = compile_tree(tree)
    bindings = bind_scene(scn, mj_model, referenced_objects(scn, _leaf_objects(tree)))
    ctrl = ControllerConfig.from_model(mj_model, site=scn.robot.tool_site, nullspace_stiffness=scn.robot.nullspace_stiffness)
    terms = build_terms(scn, bindings)
    tick_seconds = 1.0 / scn.bt_hz
    spec = EpisodeSpec(
        ct=ct,
        leaves=build_leaf_programs(ct, scn.parameter_names, bindings, scn.robot.default_stiffness, tick_seconds),
        terms=terms,
        bindings=bindings,
        ctrl=ctrl,
        default_stiffness=tuple(float(v) for v in scn.robot.default_stiffness),
        ticks=max(1, int(round(seconds * scn.bt_hz))),
        steps_per_tick=scn.steps_per_tick,
        **_success_spec(scn, bindings),
    )
    data = mujoco.MjData(mj_model)
    mujoco.mj_forward(mj_model, data)
    return Rollout(
        scenario=scn,
        worlds=worlds,
        spec=spec,
        sampler=make_sampler(scn, bindings, start_configs),
        model=mjx.put_model(mj_model),
        template=mjx.put_data(mj_model, data),
        strategy=strategy,
        chunk=chunk,
        _objective_matrix=objective_matrix(terms, len(scn.objective_names)),
        mj_model=mj_model,
    )


def _success_spec(scn: Scenario, bindings: SceneBindings) -> dict:
    s = scn.success
    target = scn.objects[s.target]
    return dict(
        success_kind=s.kind,
        success_object=bindings.slot_of[s.object],
        success_target=bindings.slot_of[s.target],
        position_tolerance=float(s.position_tolerance or 0.0),
        orientation_tolerance=math.radians(float(s.orientation_tolerance_deg or 0.0)),
        depth=float(s.depth or 0.0),
        hole_top_local=bindings.hole_top_local or (0.0, 0.0, float(target.extra.get("hole_top", 0.0))),
        hole_half_width=float(target.extra.get("hole_half_width", DEFAULT_HOLE_HALF_WIDTH)),
    )


def summarize(res: EpisodeResult, config_index, objective_matrix, reward_names, xp=jnp) -> RolloutOutput:
    """(B, W) episode results -> RolloutOutput; ``xp`` is jax.numpy or numpy (the native
    baseline reports through the same function)."""
    objectives = xp.mean(res.reward_totals @ xp.asarray(objective_matrix), axis=1)
    metrics = {f"reward_{name}": res.reward_totals[..., i] for i, name in enumerate(reward_names)}
    metrics.update(
        diverged=res.diverged,
        bt_status=res.bt_status,
        bt_success=res.bt_status == int(Status.SUCCESS),
        bt_done_tick=res.bt_done_tick,
        position_error=res.position_error,
        orientation_error_deg=xp.degrees(res.orientation_error),
        insertion_depth=res.insertion_depth,
        max_force=res.max_force,
        config_index=config_index,
    )
    return RolloutOutput(objectives=objectives, success=res.success, metrics=metrics)


def _batched_episodes(r: Rollout, params: jax.Array, worlds: Worlds) -> RolloutOutput:
    b, w = worlds.config_index.shape
    flat_params = jnp.repeat(params, w, axis=0)
    flat_worlds = jax.tree.map(lambda x: x.reshape((b * w,) + x.shape[2:]), worlds)
    episode = lambda p, wd: run_episode(r.spec, r.model, r.template, p, wd)  # noqa: E731
    # The flat B x W batch is split over all local devices (one device: unchanged).
    res: EpisodeResult = shard_batch(over_worlds(episode, r.strategy, r.chunk))(flat_params, flat_worlds)
    res = jax.tree.map(lambda x: x.reshape((b, w) + x.shape[1:]), res)
    return summarize(res, worlds.config_index, r._objective_matrix, r.reward_names)


# The Rollout is static (hashed by identity): its model, tree and leaf programs are baked into
# the trace; one compile per (rollout, batch size).
@partial(jax.jit, static_argnums=(0, 2))
def _sample(r: Rollout, key: jax.Array, batch: int) -> Worlds:
    return sample_worlds(r.sampler, key, (batch, r.worlds))


@partial(jax.jit, static_argnums=0)
def _run_worlds(r: Rollout, params: jax.Array, worlds: Worlds) -> RolloutOutput:
    return _batched_episodes(r, params, worlds)


@partial(jax.jit, static_argnums=0)
def _trace(r: Rollout, params: jax.Array, world: Worlds):
    return run_episode(r.spec, r.model, r.template, params, world, record=True)
