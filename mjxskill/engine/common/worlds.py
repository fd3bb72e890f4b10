"""Domain randomization: the initial conditions of one world, drawn from a PRNG key.

A world is a start configuration of the arm (drawn uniformly from the scenario's list), x-y
offsets of the randomized objects and goal poses (Gaussian, sigma from the YAML, optionally
clipped to +- clip_sigmas * sigma), and a friction coefficient for the randomized object's
contacts (uniform in the YAML's range, if it gives one).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjxskill.engine.common.bindings import SceneBindings, nominal_poses
from mjxskill.scenario.schema import Scenario


class Worlds(NamedTuple):
    """Initial conditions of a batch of worlds; every field has the same leading shape S.

    config_index: S int32, row of the start-configuration table used.
    arm_qpos: S + (7,) float32, start joint angles, rad.
    object_pos: S + (K, 3) float32, start/nominal position of every bound object slot, m.
    object_quat: S + (K, 4) float32, its orientation (w x y z).
    friction: S float32, sliding friction of the randomized object's contacts (NaN: keep the
      MJCF's).
    """

    config_index: jax.Array
    arm_qpos: jax.Array
    object_pos: jax.Array
    object_quat: jax.Array
    friction: jax.Array


class WorldSampler(NamedTuple):
    """Static description of the randomization (host arrays, baked into the trace).

    configs: (C, 7) start configurations. sigma: (K,) x-y standard deviation per slot (0: fixed).
    clip: multiples of sigma the offsets are clipped to (inf: none). friction_range: (2,) or
    None.
    """

    configs: np.ndarray
    nominal_pos: np.ndarray
    nominal_quat: np.ndarray
    sigma: np.ndarray
    clip: float
    friction_range: tuple[float, float] | None


def make_sampler(scn: Scenario, bindings: SceneBindings, configs: np.ndarray | None = None) -> WorldSampler:
    """``configs`` defaults to the scenario's training start configurations."""
    pos, quat = nominal_poses(bindings)
    sigma = np.array([scn.randomization.xy_sigma.get(s.name, 0.0) for s in bindings.slots], np.float32)
    clip = scn.randomization.clip_sigmas
    configs = scn.robot.start_configs if configs is None else np.asarray(configs)
    if configs.ndim != 2 or configs.shape[1] != 7 or len(configs) == 0:
        raise ValueError(f"start configurations must have shape (C, 7) with C >= 1, got {configs.shape}")
    return WorldSampler(
        configs=np.asarray(configs, np.float32),
        nominal_pos=pos,
        nominal_quat=quat,
        sigma=sigma,
        clip=float("inf") if clip is None else float(clip),
        friction_range=scn.randomization.friction_range,
    )


def sample_world(sampler: WorldSampler, key: jax.Array) -> Worlds:
    """One world from ``key`` (vmap for more)."""
    k_config, k_offset, k_friction = jax.random.split(key, 3)
    index = jax.random.randint(k_config, (), 0, len(sampler.configs))
    return world_from_config(sampler, index, k_offset, k_friction)


def world_from_config(sampler: WorldSampler, index, k_offset: jax.Array, k_friction: jax.Array) -> Worlds:
    """A world starting from configuration ``index``, with object offsets and friction drawn."""
    sigma = jnp.asarray(sampler.sigma)[:, None]
    noise = jnp.clip(jax.random.normal(k_offset, sigma.shape[:1] + (2,)), -sampler.clip, sampler.clip)
    offset = jnp.concatenate([noise * sigma, jnp.zeros_like(sigma)], axis=1)
    if sampler.friction_range is None:
        friction = jnp.float32(jnp.nan)
    else:
        lo, hi = sampler.friction_range
        friction = jax.random.uniform(k_friction, (), jnp.float32, lo, hi)
    return Worlds(
        config_index=jnp.asarray(index, jnp.int32),
        arm_qpos=jnp.asarray(sampler.configs)[index],
        object_pos=jnp.asarray(sampler.nominal_pos) + offset,
        object_quat=jnp.asarray(sampler.nominal_quat),
        friction=friction,
    )


def sample_worlds(sampler: WorldSampler, key: jax.Array, shape: tuple[int, ...]) -> Worlds:
    """Worlds of leading shape ``shape``, each from its own split of ``key``."""
    n = int(np.prod(shape))
    worlds = jax.vmap(lambda k: sample_world(sampler, k))(jax.random.split(key, n))
    return jax.tree.map(lambda x: x.reshape(shape + x.shape[1:]), worlds)


def worlds_per_config(sampler: WorldSampler, key: jax.Array, per_config: int) -> Worlds:
    """``per_config`` worlds from every start configuration: leading shape (C * per_config,),
    configuration-major (used to report success per start configuration)."""
    n_configs = len(sampler.configs)
    index = jnp.repeat(jnp.arange(n_configs), per_config)
    keys = jax.random.split(key, (n_configs * per_config, 2))
    return jax.vmap(lambda i, k: world_from_config(sampler, i, k[0], k[1]))(index, keys)


def world_pair_friction(base, pairs, friction, xp):
    """(npair, 5) contact-pair friction of one world: ``base`` (the model's ``pair_friction``) with
    the world's ``friction`` as the sliding coefficients (the first two) of the randomized
    ``pairs`` (indices), unless it is NaN (the MJCF's kept). ``xp``: the engine's array namespace
    (``mjxskill.engine.common.arrays``)."""
    mask = np.zeros(np.shape(base), bool)
    mask[list(pairs), :2] = True
    return xp.where(mask & ~xp.isnan(friction), friction, base)
