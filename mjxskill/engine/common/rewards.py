"""Reward terms of the paper (section "Reward Functions"), configured from the scenario YAML and
written once for both engines.

Each term maps an :class:`Observation` of one world at the end of a BT tick to a raw per-tick
value (or of many worlds at once, each field with a leading (N,) axis, to (N,) values: the
native engine's batch); an engine sums ``weight * raw`` over the episode's ticks, and an objective is the sum of
its rewards, averaged over the worlds of a parameter set. Larger is better everywhere. A term
also knows the worst raw value per tick, which a diverged world is charged.

Kinds, their constants and defaults: ``mjxskill.scenario.vocabulary.REWARD_KINDS`` (one table for
the loader and both engines); what each computes: ``mjxskill.scenario.schema.Reward``. The terms
are built for one engine's array namespace ``xp`` (``mjxskill.engine.common.arrays``).
"""

from __future__ import annotations

import math
from typing import Any, Callable, NamedTuple

import numpy as np

from mjxskill.engine.common.rotations import quat_angle
from mjxskill.errors import quote
from mjxskill.scenario.schema import Reward, Scenario
from mjxskill.scenario.vocabulary import REWARD_KINDS


class Observation(NamedTuple):
    """What the rewards see of one world at the end of a BT tick.

    tool_pos (3,), tool_quat (4,): tool site pose. ref_pos (3,): controller reference position.
    slot_pos (K, 3), slot_quat (K, 4): current poses of the bound scenario objects.
    wrench (6,): feed-forward wrench the controller applies (after rate limiting).
    bt_succeeded (): bool, the BT's root has returned SUCCESS.
    contact_force (): N, the measured normal contact force of the tool, mean over the tick's
    control steps (``mjxskill.sim.tool_force``).
    """

    tool_pos: Any
    tool_quat: Any
    ref_pos: Any
    slot_pos: Any
    slot_quat: Any
    wrench: Any
    bt_succeeded: Any
    contact_force: Any


class RewardTerm(NamedTuple):
    """A configured reward: ``raw(obs) -> ()`` per tick, its weight, objective index and the
    worst raw value per tick."""

    name: str
    raw: Callable[[Observation], Any]
    weight: float
    objective: int
    worst_raw: float


def exp_reward(d, sigma_w, d_o, xp):
    """The paper's exponential family r(d) = exp(-(d + d_o) / (2 sigma_w^2))."""
    return xp.exp(-(d + d_o) / (2.0 * sigma_w**2))


def build_terms(scn: Scenario, slot_of: dict, xp) -> tuple[RewardTerm, ...]:
    """The scenario's reward terms in YAML order; ``slot_of`` maps object names to slots."""
    terms = []
    for reward in scn.rewards:
        raw, raw_min, raw_max = _raw_term(reward, slot_of, xp)
        # The worst *weighted* value: a negative weight makes the largest raw value the worst.
        worst_raw = raw_min if reward.weight >= 0 else raw_max
        terms.append(RewardTerm(reward.name, raw, float(reward.weight), scn.objective_names.index(reward.objective),
                                worst_raw))
    return tuple(terms)


def raw_rewards(terms: tuple[RewardTerm, ...], obs: Observation, xp):
    """(R,) raw per-tick values of all terms."""
    return xp.stack([t.raw(obs) for t in terms]) if terms else xp.zeros((0,), xp.float_dtype)


def _target(reward: Reward, slot_of: dict, xp):
    slot = slot_of[reward.target]
    offset = np.zeros(3) if reward.target_offset is None else np.asarray(reward.target_offset, xp.float_dtype)
    return lambda obs: obs.slot_pos[..., slot, :] + offset


def _raw_term(reward: Reward, slot_of: dict, xp):
    """(raw function, smallest raw value, largest raw value) of one reward."""
    kind = reward.kind
    if kind not in REWARD_KINDS:
        raise ValueError(f"reward {quote(reward.name)}: unknown kind {quote(kind)}; expected one of {sorted(REWARD_KINDS)}")
    if kind == "task_completion":
        value = reward.constant("value")
        return (lambda obs: xp.where(obs.bt_succeeded, value, 0.0)), min(value, 0.0), max(value, 0.0)
    if kind == "ee_distance_to_box":
        w, d_o = reward.constant("w"), reward.constant("d_o")
        target = _target(reward, slot_of, xp)
        largest = 1.0 / (w * d_o) if d_o > 0 else math.inf
        return (lambda obs: 1.0 / (w * (xp.linalg.norm(obs.tool_pos - target(obs), axis=-1) + d_o))), 0.0, largest
    if kind == "applied_wrench":
        cap = reward.constant("cap")
        return (lambda obs: xp.minimum(xp.sum(xp.abs(obs.wrench[..., :3]), axis=-1), cap)), 0.0, cap
    if kind == "contact_force":
        cap = reward.constant("cap")
        return (lambda obs: xp.minimum(obs.contact_force, cap)), 0.0, cap
    sigma_w, d_o = reward.constant("sigma_w"), reward.constant("d_o")
    best = math.exp(-d_o / (2.0 * sigma_w**2))
    if kind == "exp_ee_to_goal":
        target = _target(reward, slot_of, xp)
        return (lambda obs: exp_reward(xp.linalg.norm(obs.tool_pos - target(obs), axis=-1), sigma_w, d_o, xp)), 0.0, best
    if kind == "exp_ee_to_reference":
        return (lambda obs: exp_reward(xp.linalg.norm(obs.tool_pos - obs.ref_pos, axis=-1), sigma_w, d_o, xp)), 0.0, best
    if kind == "object_pose_divergence":
        w_pos, w_rot = reward.constant("position_weight"), reward.constant("orientation_weight")
        obj, tgt = slot_of[reward.object], slot_of[reward.target]

        def divergence(obs):
            d_pos = xp.linalg.norm(obs.slot_pos[..., obj, :] - obs.slot_pos[..., tgt, :], axis=-1)
            d_rot = quat_angle(obs.slot_quat[..., obj, :], obs.slot_quat[..., tgt, :], xp)
            return w_pos * exp_reward(d_pos, sigma_w, d_o, xp) + w_rot * exp_reward(d_rot, sigma_w, d_o, xp)

        return divergence, 0.0, (w_pos + w_rot) * best
