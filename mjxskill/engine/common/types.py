"""What both physics engines share: the static facts of an episode, its result types, and the
summary of a batch of episodes into objectives and metrics.

The compiled MJX rollout (``mjxskill.engine.mjx.compiled``) and the native MuJoCo engine
(``mjxskill.engine.native``) both import this module (and ``bindings``, ``worlds``); neither imports
the other, so the native engine stays an independent reference for the compiled one. Nothing
here imports MJX.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, NamedTuple

import mujoco
import numpy as np

from mjxskill.ebt.nodes import Status
from mjxskill.engine.common.bindings import SceneBindings, bind_scene, referenced_objects
from mjxskill.sim.controller_config import ControllerConfig
from mjxskill.sim.model import held_item
from mjxskill.sim.shapes import hole_half_widths, hole_radius

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario.schema import Scenario
    from mjxskill.task import PlannedTask

# Divergence containment (both engines): a world whose joints spin faster than MAX_QVEL or whose
# free objects sink below MIN_OBJECT_Z is marked diverged and frozen at its last good state.
MAX_QVEL = 100.0  # rad/s (or m/s for free objects): far beyond anything the arm can do
MIN_OBJECT_Z = -0.05  # m: a free object this far below the table top fell through it


class SuccessTest(NamedTuple):
    """The scenario's success test with its objects as slot indices (host values; meanings:
    ``mjxskill.scenario.schema.Success``). orientation_tolerance: rad (inf: not tested).
    hole_top (3,), hole_half_width (2,): the target's hole in its frame (inserted); hole_round:
    the hole is round, of radius hole_half_width[0].
    region_center (3,), region_half (3,): the region in the target's frame (object_in_region)."""

    kind: str
    object: int
    target: int
    position_tolerance: float
    orientation_tolerance: float
    depth: float
    hole_top: tuple[float, float, float]
    hole_half_width: tuple[float, ...]
    hole_round: bool
    region_center: tuple[float, ...]
    region_half: tuple[float, ...]


class EpisodeSetup(NamedTuple):
    """Everything static about an episode that does not depend on the engine (host values).

    bindings: scenario objects <-> MJCF bodies. ctrl: the impedance controller's settings.
    default_stiffness (6,): when no skill sets one. ticks: BT ticks per episode;
    steps_per_tick: control steps per tick. success: the scenario's success test.
    """

    bindings: SceneBindings
    ctrl: ControllerConfig
    default_stiffness: tuple[float, ...]
    ticks: int
    steps_per_tick: int
    success: SuccessTest


def leaf_objects(tree) -> list[str]:
    """Scenario objects the tree's goal-setting leaves name, in pre-order."""
    return [leaf.args["object"] for leaf in tree.leaves() if leaf.primitive == "set_goal_from_object"]


def _floats(values, n: int) -> tuple[float, ...]:
    return tuple(float(v) for v in (np.zeros(n) if values is None else values))


def success_test(scn: Scenario, bindings: SceneBindings) -> SuccessTest:
    """The scenario's success test over ``bindings``' slots."""
    s = scn.success
    target = scn.objects[s.target]
    hole_half: tuple[float, ...]
    hole_top, hole_half = (0.0, 0.0, 0.0), (0.0, 0.0)
    hole_round = target.shape == "box_with_round_hole"
    if s.kind == "inserted":  # the loader checked the target is a box with a hole
        hole_top = (0.0, 0.0, float(target.size[2]))
        if hole_round:
            hole_half = (hole_radius(target.extra, held_item(scn)),) * 2
        else:
            hole_half = _floats(hole_half_widths(target.extra, held_item(scn)), 2)
    tolerance = s.orientation_tolerance_deg
    return SuccessTest(
        kind=s.kind,
        object=bindings.slot_of[s.object],
        target=bindings.slot_of[s.target],
        position_tolerance=float(s.position_tolerance or 0.0),
        orientation_tolerance=math.inf if tolerance is None else math.radians(float(tolerance)),
        depth=float(s.depth or 0.0),
        hole_top=hole_top,
        hole_half_width=hole_half,
        hole_round=hole_round,
        region_center=_floats(s.region_center, 3),
        region_half=_floats(None if s.region_size is None else np.asarray(s.region_size) / 2, 3),
    )


def episode_setup(scn: Scenario, task: PlannedTask, mj_model: mujoco.MjModel, episode_seconds: float) -> EpisodeSetup:
    """The engine-independent facts of ``task``'s episodes in ``scn`` on ``mj_model``."""
    bindings = bind_scene(scn, mj_model, referenced_objects(scn, leaf_objects(task.tree)))
    return EpisodeSetup(
        bindings=bindings,
        ctrl=ControllerConfig.from_model(mj_model, site=scn.robot.tool_site, nullspace_stiffness=scn.robot.nullspace_stiffness),
        default_stiffness=tuple(float(v) for v in scn.robot.default_stiffness),
        ticks=max(1, int(round(episode_seconds * scn.bt_hz))),
        steps_per_tick=scn.steps_per_tick,
        success=success_test(scn, bindings),
    )


# The values of an episode's result and record: numpy arrays or Python scalars on the native engine
# (one episode each), jax arrays inside MJX's traced programs (a batch of episodes).
Values = Any


class EpisodeResult(NamedTuple):
    """Per-world outcome (scalars unless noted).

    reward_totals (R,): sum over ticks of each term's raw value (worst values if diverged).
    success: the scenario's success test at the end. diverged: physics blew up. bt_status: the
    root's last status (RUNNING if it never finished). bt_done_tick: tick the root finished (-1:
    never). position_error m, orientation_error rad: success object to target at the end (peg:
    tool to hole axis, 0). insertion_depth m: below the hole's top (peg; 0 for push).
    peak_commanded_force N: largest |feed-forward force| the skills commanded (after the
    controller's rate limits). peak_contact_force, mean_contact_force N: the largest and the
    mean over the control steps of the measured normal contact force between the tool (or
    held item) and everything else (``mjxskill.sim.tool_force``).
    """

    reward_totals: Values
    success: Values
    diverged: Values
    bt_status: Values
    bt_done_tick: Values
    position_error: Values
    orientation_error: Values
    insertion_depth: Values
    peak_commanded_force: Values
    peak_contact_force: Values
    mean_contact_force: Values


class TickRecord(NamedTuple):
    """Per-tick trace of one world (only when asked for: it grows with the episode).

    qpos (nq,): joint and object positions at the end of the tick; mocap_pos (M, 3), mocap_quat
    (M, 4): the mocap bodies (the world's goal, fixtures) as the world placed them (for
    rendering). tool_pos (3,), ref_pos (3,): tool and reference positions. root: root status
    this tick. active (L,) bool: the leaves ticked. rewards (R,): raw reward values of the tick.
    """

    qpos: Values
    mocap_pos: Values
    mocap_quat: Values
    tool_pos: Values
    ref_pos: Values
    root: Values
    active: Values
    rewards: Values


class RolloutOutput(NamedTuple):
    """objectives (B, O) float32; success (B, W) bool; metrics: name -> (B, W) array
    (``reward_<name>`` totals per world, ``diverged``, ``bt_status``, ``bt_done_tick``,
    ``position_error`` m, ``orientation_error_deg``, ``insertion_depth`` m,
    ``peak_commanded_force``, ``peak_contact_force``, ``mean_contact_force`` N, ``config_index``)."""

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
        peak_commanded_force=res.peak_commanded_force,
        peak_contact_force=res.peak_contact_force,
        mean_contact_force=res.mean_contact_force,
        config_index=config_index,
    )
    return RolloutOutput(objectives=objectives, success=res.success, metrics=metrics)
