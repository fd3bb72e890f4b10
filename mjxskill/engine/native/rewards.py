"""The reward terms of ``mjxskill.engine.mjx.rewards`` in numpy, for the native-MuJoCo baseline.

Same kinds, constants and defaults (``mjxskill.scenario.vocabulary.REWARD_KINDS``); a term maps one :class:`NativeObservation` (end of a BT tick)
to a raw float, and knows the worst raw value a diverged world is charged per tick.
"""

from __future__ import annotations

import math
from typing import Callable, NamedTuple

import numpy as np

from mjxskill.engine.native.motion import quat_angle
from mjxskill.scenario.schema import Reward, Scenario
from mjxskill.scenario.vocabulary import REWARD_KINDS


class NativeObservation(NamedTuple):
    """tool_pos (3,), tool_quat (4,), ref_pos (3,), slot_pos (K, 3), slot_quat (K, 4), wrench (6,)
    (after the controller's rate limits), bt_succeeded: bool, contact_force: N, the tool's measured
    normal contact force, mean over the tick's control steps."""

    tool_pos: np.ndarray
    tool_quat: np.ndarray
    ref_pos: np.ndarray
    slot_pos: np.ndarray
    slot_quat: np.ndarray
    wrench: np.ndarray
    bt_succeeded: bool
    contact_force: float


class NativeRewardTerm(NamedTuple):
    name: str
    raw: Callable[[NativeObservation], float]
    weight: float
    objective: int
    worst_raw: float


def _exp(d: float, sigma_w: float, d_o: float) -> float:
    return math.exp(-(d + d_o) / (2.0 * sigma_w**2))


def build_native_terms(scn: Scenario, slot_of: dict) -> tuple[NativeRewardTerm, ...]:
    """The scenario's reward terms in YAML order; ``slot_of`` maps object names to slots."""
    terms = []
    for reward in scn.rewards:
        raw, raw_min, raw_max = _raw_term(reward, slot_of)
        # the worst weighted value: a negative weight makes the largest raw value the worst
        worst_raw = raw_min if reward.weight >= 0 else raw_max
        terms.append(NativeRewardTerm(reward.name, raw, float(reward.weight),
                                      scn.objective_names.index(reward.objective), worst_raw))
    return tuple(terms)


def _raw_term(reward: Reward, slot_of: dict):
    """(raw function, smallest raw value, largest raw value)."""
    kind = reward.kind
    if kind not in REWARD_KINDS:
        raise ValueError(f"reward {reward.name!r}: unknown kind {kind!r}; expected one of {sorted(REWARD_KINDS)}")
    target = None
    if reward.target is not None:
        slot = slot_of[reward.target]
        offset = np.zeros(3) if reward.target_offset is None else np.asarray(reward.target_offset, float)
        target = lambda obs: obs.slot_pos[slot] + offset  # noqa: E731
    if kind == "task_completion":
        value = reward.constant("value")
        return (lambda obs: value if obs.bt_succeeded else 0.0), min(value, 0.0), max(value, 0.0)
    if kind == "ee_distance_to_box":
        w, d_o = reward.constant("w"), reward.constant("d_o")
        largest = 1.0 / (w * d_o) if d_o > 0 else math.inf
        return (lambda obs: 1.0 / (w * (np.linalg.norm(obs.tool_pos - target(obs)) + d_o))), 0.0, largest
    if kind == "applied_wrench":
        cap = reward.constant("cap")
        return (lambda obs: min(float(np.sum(np.abs(obs.wrench[:3]))), cap)), 0.0, cap
    if kind == "contact_force":
        cap = reward.constant("cap")
        return (lambda obs: min(float(obs.contact_force), cap)), 0.0, cap
    sigma_w, d_o = reward.constant("sigma_w"), reward.constant("d_o")
    best = math.exp(-d_o / (2.0 * sigma_w**2))
    if kind == "exp_ee_to_goal":
        return (lambda obs: _exp(float(np.linalg.norm(obs.tool_pos - target(obs))), sigma_w, d_o)), 0.0, best
    if kind == "exp_ee_to_reference":
        return (lambda obs: _exp(float(np.linalg.norm(obs.tool_pos - obs.ref_pos)), sigma_w, d_o)), 0.0, best
    if kind == "object_pose_divergence":
        w_pos, w_rot = reward.constant("position_weight"), reward.constant("orientation_weight")
        obj, tgt = slot_of[reward.object], slot_of[reward.target]

        def divergence(obs):
            d_pos = float(np.linalg.norm(obs.slot_pos[obj] - obs.slot_pos[tgt]))
            d_rot = quat_angle(obs.slot_quat[obj], obs.slot_quat[tgt])
            return w_pos * _exp(d_pos, sigma_w, d_o) + w_rot * _exp(d_rot, sigma_w, d_o)

        return divergence, 0.0, (w_pos + w_rot) * best
