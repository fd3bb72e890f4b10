"""Inputs for the compiled-rollout tests: parameter rows by name and hand-placed worlds."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjxskill.engine.mjx import Worlds
from mjxskill.engine.common.bindings import nominal_poses


def params_of(task, *rows) -> np.ndarray:
    """(len(rows), P) float32: the skill defaults of ``task`` (a PlannedTask or a rollout's)
    with each row's {parameter name: value} set."""
    task = getattr(task, "task", task)
    out = np.tile(task.defaults, (len(rows), 1)).astype(np.float32)
    for i, row in enumerate(rows):
        for name, value in row.items():
            out[i, task.parameter_names.index(name)] = value
    return out


def native_like(rollout):
    """The native engine (its default worker processes) with the compiled ``rollout``'s task and settings."""
    from mjxskill.engine.build import build_rollout

    return build_rollout(rollout.scenario, rollout.task, "native", worlds=rollout.worlds,
                         episode_seconds=rollout.episode_seconds)


def placed_worlds(rollout, cases) -> Worlds:
    """Worlds (W,) from cases (start configuration, {object: (dx, dy) m from its nominal pose},
    friction or None to keep the sampled one); objects not named stay at their nominal poses."""
    bindings = rollout.setup.bindings
    nominal = nominal_poses(bindings)[0]
    worlds = []
    for config, offsets, friction in cases:
        base = jax.tree.map(lambda x: x[config], rollout.worlds_per_config(jax.random.key(0), 1))
        pos = nominal.copy()
        for name, offset in offsets.items():
            pos[bindings.slot_of[name], :2] += np.asarray(offset, np.float32)
        world = base._replace(object_pos=jnp.asarray(pos))
        if friction is not None:
            world = world._replace(friction=jnp.float32(friction))
        worlds.append(world)
    return jax.tree.map(lambda *xs: jnp.stack(xs), *worlds)
