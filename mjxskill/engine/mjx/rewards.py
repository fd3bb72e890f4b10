"""Reward terms of the paper (section "Reward Functions"), configured from the scenario YAML.

Each term maps an :class:`Observation` of one world at one BT tick to a raw per-tick value; the
rollout sums ``weight * raw`` over the episode's ticks, and an objective is the sum of its
rewards, averaged over the worlds of a parameter set. Larger is better everywhere.

Kinds, their constants and defaults: ``mjxskill.scenario.vocabulary.REWARD_KINDS`` (one table for
the loader and both engines); what each computes: ``mjxskill.scenario.schema.Reward``.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjxskill.engine.common.bindings import SceneBindings
from mjxskill.scenario.schema import Reward, Scenario
from mjxskill.scenario.vocabulary import REWARD_KINDS
from mjxskill.engine.common.rotations import quat_angle

class Observation(NamedTuple):
    """What the rewards see of one world at the end of a BT tick.

    tool_pos (3,), tool_quat (4,): tool site pose. ref_pos (3,): controller reference position.
    slot_pos (K, 3), slot_quat (K, 4): current poses of the bound scenario objects.
    wrench (6,): feed-forward wrench the controller applies (after rate limiting).
    bt_succeeded (): bool, the BT's root has returned SUCCESS.
    contact_force (): N, the measured normal contact force of the tool, mean over the tick's
    control steps (``mjxskill.sim.tool_force``).
    """

    tool_pos: jax.Array
    tool_quat: jax.Array
    ref_pos: jax.Array
    slot_pos: jax.Array
    slot_quat: jax.Array
    wrench: jax.Array
    bt_succeeded: jax.Array
    contact_force: jax.Array


def exp_reward(d, sigma_w, d_o):
    """The paper's exponential family r(d) = exp(-(d + d_o) / (2 sigma_w^2))."""
    return jnp.exp(-(d + d_o) / (2.0 * sigma_w**2))


class RewardTerm(NamedTuple):
    """A configured reward: ``raw(obs) -> ()`` per tick, its weight, objective index and the
    worst raw value per tick (what a diverged world is charged)."""

    name: str
    raw: Callable[[Observation], jax.Array]
    weight: float
    objective: int
    worst_raw: float


def build_terms(scn: Scenario, bindings: SceneBindings) -> tuple[RewardTerm, ...]:
    """Reward terms of the scenario, in YAML order (host-side; the closures trace into jit)."""
    terms = []
    for reward in scn.rewards:
        raw, raw_min, raw_max = _raw_term(reward, bindings)
        # The worst *weighted* value: a negative weight makes the largest raw value the worst.
        worst_raw = raw_min if reward.weight >= 0 else raw_max
        terms.append(RewardTerm(reward.name, raw, float(reward.weight), scn.objective_names.index(reward.objective), worst_raw))
    return tuple(terms)


def _target(reward: Reward, bindings: SceneBindings):
    slot = bindings.slot_of[reward.target]
    offset = np.zeros(3) if reward.target_offset is None else np.asarray(reward.target_offset, np.float32)
    return lambda obs: obs.slot_pos[slot] + offset


def _raw_term(reward: Reward, bindings: SceneBindings):
    """(raw function, smallest raw value, largest raw value) of one reward."""
    kind = reward.kind
    if kind not in REWARD_KINDS:
        raise ValueError(f"reward {reward.name!r}: unknown kind {kind!r}; expected one of {sorted(REWARD_KINDS)}")
    if kind == "task_completion":
        value = reward.constant("value")
        return (lambda obs: jnp.where(obs.bt_succeeded, value, 0.0)), min(value, 0.0), max(value, 0.0)
    if kind == "ee_distance_to_box":
        w, d_o = reward.constant("w"), reward.constant("d_o")
        target = _target(reward, bindings)
        largest = 1.0 / (w * d_o) if d_o > 0 else float("inf")
        return (lambda obs: 1.0 / (w * (jnp.linalg.norm(obs.tool_pos - target(obs)) + d_o))), 0.0, largest
    if kind == "applied_wrench":
        cap = reward.constant("cap")
        return (lambda obs: jnp.minimum(jnp.sum(jnp.abs(obs.wrench[:3])), cap)), 0.0, cap
    if kind == "contact_force":
        cap = reward.constant("cap")
        return (lambda obs: jnp.minimum(obs.contact_force, cap)), 0.0, cap
    sigma_w, d_o = reward.constant("sigma_w"), reward.constant("d_o")
    best = float(np.exp(-d_o / (2.0 * sigma_w**2)))
    if kind == "exp_ee_to_goal":
        target = _target(reward, bindings)
        return (lambda obs: exp_reward(jnp.linalg.norm(obs.tool_pos - target(obs)), sigma_w, d_o)), 0.0, best
    if kind == "exp_ee_to_reference":
        return (lambda obs: exp_reward(jnp.linalg.norm(obs.tool_pos - obs.ref_pos), sigma_w, d_o)), 0.0, best
    if kind == "object_pose_divergence":
        w_pos = reward.constant("position_weight")
        w_rot = reward.constant("orientation_weight")
        obj, tgt = bindings.slot_of[reward.object], bindings.slot_of[reward.target]

        def divergence(obs):
            d_pos = jnp.linalg.norm(obs.slot_pos[obj] - obs.slot_pos[tgt])
            d_rot = quat_angle(obs.slot_quat[obj], obs.slot_quat[tgt])
            return w_pos * exp_reward(d_pos, sigma_w, d_o) + w_rot * exp_reward(d_rot, sigma_w, d_o)

        return divergence, 0.0, (w_pos + w_rot) * best


def raw_rewards(terms: tuple[RewardTerm, ...], obs: Observation) -> jax.Array:
    """(R,) raw per-tick values of all terms."""
    return jnp.stack([t.raw(obs) for t in terms]) if terms else jnp.zeros((0,))
