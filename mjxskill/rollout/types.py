"""What both physics engines share: the static facts of an episode, its result types, and the
summary of a batch of episodes into objectives and metrics.

The compiled MJX rollout (``mjxskill.rollout.compiled``) and the native MuJoCo engine
(``mjxskill.native``) both import this module (and ``bindings``, ``worlds``); neither imports
the other, so the native engine stays an independent reference for the compiled one. Nothing
here imports MJX.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import mujoco
import numpy as np

from mjxskill.ebt.nodes import Status
from mjxskill.rollout.bindings import SceneBindings, bind_scene, referenced_objects
from mjxskill.sim.controller_config import ControllerConfig

# Divergence containment (both engines): a world whose joints spin faster than MAX_QVEL or whose
# free objects sink below MIN_OBJECT_Z is marked diverged and frozen at its last good state.
MAX_QVEL = 100.0  # rad/s (or m/s for free objects): far beyond anything the arm can do
MIN_OBJECT_Z = -0.05  # m: a free object this far below the table top fell through it
DEFAULT_HOLE_HALF_WIDTH = 0.02  # m: a peg tip inside this square around the hole axis is "in"


class EpisodeSetup(NamedTuple):
    """Everything static about an episode that does not depend on the engine (host values).

    bindings: scenario objects <-> MJCF bodies. ctrl: the impedance controller's settings.
    default_stiffness (6,): when no skill sets one. ticks: BT ticks per episode;
    steps_per_tick: control steps per tick. success_*: the scenario's success test with its
    objects as slot indices (see ``mjxskill.scenario.schema.Success``); orientation_tolerance
    in rad; hole_top_local (3,): the hole's top in the target's frame.
    """

    bindings: SceneBindings
    ctrl: ControllerConfig
    default_stiffness: tuple[float, ...]
    ticks: int
    steps_per_tick: int
    success_kind: str  # "object_at_pose" or "inserted"
    success_object: int  # slot index
    success_target: int  # slot index
    position_tolerance: float
    orientation_tolerance: float  # rad
    depth: float
    hole_top_local: tuple[float, float, float]
    hole_half_width: float


def leaf_objects(tree) -> list[str]:
    """Scenario objects the tree's goal-setting leaves name, in pre-order."""
    return [leaf.args["object"] for leaf in tree.leaves() if leaf.primitive == "set_goal_from_object"]


def episode_setup(scn, task, mj_model: mujoco.MjModel, episode_seconds: float) -> EpisodeSetup:
    """The engine-independent facts of ``task``'s episodes in ``scn`` on ``mj_model``."""
    bindings = bind_scene(scn, mj_model, referenced_objects(scn, leaf_objects(task.tree)))
    s = scn.success
    target = scn.objects[s.target]
    return EpisodeSetup(
        bindings=bindings,
        ctrl=ControllerConfig.from_model(mj_model, site=scn.robot.tool_site, nullspace_stiffness=scn.robot.nullspace_stiffness),
        default_stiffness=tuple(float(v) for v in scn.robot.default_stiffness),
        ticks=max(1, int(round(episode_seconds * scn.bt_hz))),
        steps_per_tick=scn.steps_per_tick,
        success_kind=s.kind,
        success_object=bindings.slot_of[s.object],
        success_target=bindings.slot_of[s.target],
        position_tolerance=float(s.position_tolerance or 0.0),
        orientation_tolerance=math.radians(float(s.orientation_tolerance_deg or 0.0)),
        depth=float(s.depth or 0.0),
        hole_top_local=bindings.hole_top_local or (0.0, 0.0, float(target.extra.get("hole_top", 0.0))),
        hole_half_width=float(target.extra.get("hole_half_width", DEFAULT_HOLE_HALF_WIDTH)),
    )


class EpisodeResult(NamedTuple):
    """Per-world outcome (scalars unless noted).

    reward_totals (R,): sum over ticks of each term's raw value (worst values if diverged).
    success: the scenario's success test at the end. diverged: physics blew up. bt_status: the
    root's last status (RUNNING if it never finished). bt_done_tick: tick the root finished (-1:
    never). position_error m, orientation_error rad: success object to target at the end (peg:
    tool to hole axis, 0). insertion_depth m: below the hole's top (peg; 0 for push).
    max_force N: largest |feed-forward force| commanded.
    """

    reward_totals: np.ndarray
    success: np.ndarray
    diverged: np.ndarray
    bt_status: np.ndarray
    bt_done_tick: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    insertion_depth: np.ndarray
    max_force: np.ndarray


class TickRecord(NamedTuple):
    """Per-tick trace of one world (only when asked for: it grows with the episode).

    qpos (nq,): joint and object positions at the end of the tick (for rendering).
    tool_pos (3,), ref_pos (3,): tool and reference positions. root: root status this tick.
    active (L,) bool: the leaves ticked. rewards (R,): raw reward values of the tick.
    """

    qpos: np.ndarray
    tool_pos: np.ndarray
    ref_pos: np.ndarray
    root: np.ndarray
    active: np.ndarray
    rewards: np.ndarray


class RolloutOutput(NamedTuple):
    """objectives (B, O) float32; success (B, W) bool; metrics: name -> (B, W) array
    (``reward_<name>`` totals per world, ``diverged``, ``bt_status``, ``bt_done_tick``,
    ``position_error`` m, ``orientation_error_deg``, ``insertion_depth`` m, ``max_force`` N,
    ``config_index``)."""

    objectives: np.ndarray
    success: np.ndarray
    metrics: dict


def objective_matrix(terms, n_objectives: int, dtype=np.float32) -> np.ndarray:
    """(R, O) weights mapping summed raw rewards to objectives (``terms``: any sequence with
    ``weight`` and ``objective`` index fields)."""
    m = np.zeros((len(terms), n_objectives), dtype)
    for r, t in enumerate(terms):
        m[r, t.objective] = t.weight
    return m


def summarize(res: EpisodeResult, config_index, objective_matrix, reward_names, xp=np) -> RolloutOutput:
    """(B, W) episode results -> RolloutOutput; ``xp`` is numpy or jax.numpy (each engine
    reports through this one function)."""
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
