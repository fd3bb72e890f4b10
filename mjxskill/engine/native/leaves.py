"""The leaf programs of ``mjxskill.engine.mjx.leaves`` in plain Python, for the native engine:
each leaf's status (from the state before the tick) and effect (on the blackboard, in tick
order), over one episode's blackboard (``NativeBlackboard``: the plain loop and the lockstep,
the references) and over the rows of a batch's blackboards at once (``RowsBoard``: the same
operations on each row, so the same values).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from mjxskill.ebt.nodes import Node, Status
from mjxskill.ebt.primitives import SPIRAL_NORMAL, LeafRegistry, goal_orientation
from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.leaf_inputs import LeafInput, force_inputs, leaf_input, spiral_inputs, wait_ticks
from mjxskill.engine.common.rotations import quat_mul
from mjxskill.engine.common.tool import TOOL_DOWN, TOOL_SYMMETRY, tool_yaw
from mjxskill.engine.native.blackboard import NativeBlackboard
from mjxskill.engine.native.motion import LinearMotion, plane_basis
from mjxskill.errors import quote


class LeafStatus:
    """A leaf's status from the state before the tick: called with one blackboard, the tool
    position (3,) and whether the leaf runs on from the last tick; ``rows(board, rows, tool_pos,
    live)`` for the rows (m,) of a ``RowsBoard`` at once, their tool positions (m, 3) and live
    (m,) bool, as (m,) int Status values (what a batch's compiled tree ticks on)."""

    def __call__(self, bb: NativeBlackboard, tool_pos: np.ndarray, live: bool) -> Status:
        raise NotImplementedError

    def rows(self, board, rows: np.ndarray, tool_pos: np.ndarray, live: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class Always(LeafStatus):
    """The same status every tick."""

    def __init__(self, status: Status):
        self.status = status

    def __call__(self, bb, tool_pos, live):
        return self.status

    def rows(self, board, rows, tool_pos, live):
        return np.full(len(rows), int(self.status))


class Reached(LeafStatus):
    """SUCCESS once the tool is within ``threshold`` (m) of the running motion's goal, on a tick
    after the leaf's first (its first tick starts the motion it waits for)."""

    def __init__(self, threshold: float):
        self.threshold = threshold

    def __call__(self, bb, tool_pos, live):
        close = _distance(tool_pos, bb.motion.goal_pos) < self.threshold
        return Status.SUCCESS if live and close else Status.RUNNING

    def rows(self, board, rows, tool_pos, live):
        close = _distance(tool_pos, board.motion_goal[rows]) < self.threshold
        return np.where(live & close, int(Status.SUCCESS), int(Status.RUNNING))


def _distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| over the last axis, one formula for one position and for rows (a norm of one
    vector, a BLAS dot product, may round otherwise than one over rows: a tool on the
    threshold would be reached in one and not the other)."""
    d = a - b
    return np.sqrt(np.add.reduce(d * d, axis=-1))


class Waited(LeafStatus):
    """SUCCESS once leaf ``leaf`` has been ticked ``ticks`` times in a row."""

    def __init__(self, leaf: int, ticks: int):
        self.leaf, self.ticks = leaf, ticks

    def __call__(self, bb, tool_pos, live):
        return Status.SUCCESS if live and bb.leaf_ticks[self.leaf] >= self.ticks else Status.RUNNING

    def rows(self, board, rows, tool_pos, live):
        waited = board.leaf_ticks[rows, self.leaf] >= self.ticks
        return np.where(live & waited, int(Status.SUCCESS), int(Status.RUNNING))


class Effect:
    """What an active leaf does to the blackboard: ``effect(bb, fresh, params)`` on one episode's
    (``fresh``: the leaf starts afresh this tick, params (P,)); ``rows(board, rows, fresh,
    params)`` on the rows (m,) of a ``RowsBoard`` where the leaf is active, fresh (m,) bool and
    params (m, P), each row as the call on its own blackboard would."""

    def __call__(self, bb: NativeBlackboard, fresh: bool, params: np.ndarray) -> None:
        return None

    def rows(self, board, rows: np.ndarray, fresh: np.ndarray, params: np.ndarray) -> None:
        return None


class _Reader:
    """A leaf input (``leaf_inputs.LeafInput``) read from one parameter vector (P,), as a
    float, or from rows (m, P), as (m,)."""

    def __init__(self, source: LeafInput):
        self.index, self.value = source.index, source.value

    def __call__(self, params: np.ndarray) -> float:
        return float(params[self.index]) if self.index is not None else self.value

    def rows(self, params: np.ndarray) -> np.ndarray:
        return params[:, self.index] if self.index is not None else np.full(len(params), self.value)


def _input(leaf: Node, name: str, index: dict) -> _Reader:
    return _Reader(leaf_input(leaf, name, index))


_keep = Effect()
_running = Always(Status.RUNNING)


def tool_down_aligned(current_quat, object_yaw: float, tilt=None) -> np.ndarray:
    """(4,) tool pointing down (rotation by pi about y, then ``yaw`` about world z), with the
    yaw among the square tool's quarter-turn symmetric ones that aligns its faces with
    ``object_yaw`` (rad) nearest the current orientation (4,), tilted by ``tilt`` (roll, pitch)
    rad about the turned frame's x then y axes (None: not tilted)."""
    yaw = tool_yaw(current_quat)
    target = yaw + (object_yaw - yaw + TOOL_SYMMETRY / 2) % TOOL_SYMMETRY - TOOL_SYMMETRY / 2
    down = TOOL_DOWN
    if tilt is not None:
        roll, pitch = tilt
        about_x = [math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0]
        about_y = [math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0]
        down = quat_mul(quat_mul(about_y, about_x, HOST), down, HOST)
    return quat_mul([math.cos(target / 2), 0.0, 0.0, math.sin(target / 2)], down, HOST)


def build_native_leaves(leaves: list[Node], parameter_names, slot_of: dict, nominal_pos: np.ndarray,
                        nominal_quat: np.ndarray, tick_seconds: float) -> list[tuple[LeafStatus, Effect]]:
    """(status, effect) per leaf, in pre-order. nominal_pos (K, 3), nominal_quat (K, 4): the
    world model's object poses (the skills see the YAML, not the randomized world)."""
    ctx = _Context({name: i for i, name in enumerate(parameter_names)}, slot_of, nominal_pos, nominal_quat, tick_seconds)
    return [LEAF_PROGRAMS.build(i, leaf, ctx) for i, leaf in enumerate(leaves)]


class _Context(NamedTuple):
    """What leaf programs are built from: parameter name -> index, object name -> slot, the
    world model's slot poses (K, 3), (K, 4) and the BT tick period (s)."""

    index: dict  # type: ignore[assignment]  # a field named like tuple.index, which it shadows
    slot_of: dict
    nominal_pos: np.ndarray
    nominal_quat: np.ndarray
    tick_seconds: float


# primitive -> (leaf number, leaf, _Context) -> (status, effect): every mjxskill.ebt.primitives.PRIMITIVES
LEAF_PROGRAMS = LeafRegistry()


class SetGoal(Effect):
    """The goal: an object's nominal position plus offsets, the tool pointing down, turned by a
    yaw (and tilted) from the object's or the reference's yaw. The orientation is computed when
    a starting motion reads it (``defer_goal_quat``): the leaf runs every tick its sequence is
    ticked, and a moving reference makes it new each time."""

    def __init__(self, base, dx: _Reader, dy: _Reader, yaw: _Reader, roll: _Reader, pitch: _Reader, tilted: bool,
                 object_yaw: float, aligned: bool):
        self.base, self.dx, self.dy, self.yaw, self.roll, self.pitch = base, dx, dy, yaw, roll, pitch
        self.tilted, self.object_yaw, self.aligned = tilted, object_yaw, aligned

    def goal_quat(self, current: np.ndarray, params: np.ndarray) -> np.ndarray:
        """The goal orientation (4,) from the reference orientation ``current`` (4,), params (P,)."""
        target = (self.object_yaw if self.aligned else tool_yaw(current)) + math.radians(self.yaw(params))
        tilt = (math.radians(self.roll(params)), math.radians(self.pitch(params))) if self.tilted else None
        return tool_down_aligned(current, target, tilt)

    def __call__(self, bb, fresh, params):
        bb.goal_pos = self.base + np.array([self.dx(params), self.dy(params), 0.0])
        current = bb.reference()[1]
        bb.defer_goal_quat(lambda: self.goal_quat(current, params))

    def rows(self, board, rows, fresh, params):
        offsets = np.zeros((len(rows), 3))
        offsets[:, 0], offsets[:, 1] = self.dx.rows(params), self.dy.rows(params)
        board.goal_pos[rows] = self.base + offsets
        board.defer_goal_quat(rows, self, board.reference(rows)[1])


class StartMotion(Effect):
    """A straight-line motion from the reference to the goal, started when the leaf starts."""

    def __call__(self, bb, fresh, params):
        if fresh:
            pos, quat = bb.reference()
            bb.motion = LinearMotion(pos, quat, bb.goal_pos, bb.goal_quat)
            bb.mg_time = 0.0

    def rows(self, board, rows, fresh, params):
        for r in rows[fresh]:  # a few a episode: one by one
            board.start_motion(int(r))


class SetStiffness(Effect):
    def __init__(self, stiffness: np.ndarray):
        self.stiffness = stiffness

    def __call__(self, bb, fresh, params):
        bb.stiffness = self.stiffness

    def rows(self, board, rows, fresh, params):
        board.stiffness[rows] = self.stiffness


class ApplyForce(Effect):
    """The commanded wrench: the leaf's ``wrench`` with the force axes its inputs set."""

    def __init__(self, base: np.ndarray, overrides: list[tuple[int, _Reader]]):
        self.base, self.overrides = base, overrides

    def __call__(self, bb, fresh, params):
        wrench = self.base.copy()
        for axis, value in self.overrides:
            wrench[axis] = value(params)
        bb.wrench = wrench

    def rows(self, board, rows, fresh, params):
        wrench = np.tile(self.base, (len(rows), 1))
        for axis, value in self.overrides:
            wrench[:, axis] = value.rows(params)
        board.wrench[rows] = wrench


class OverlaySpiral(Effect):
    """The search spiral on the motion's reference, restarted when the leaf starts."""

    def __init__(self, radius: _Reader, velocity: _Reader, pitch: _Reader, axes: tuple[np.ndarray, np.ndarray]):
        self.radius, self.velocity, self.pitch, self.axes = radius, velocity, pitch, axes

    def __call__(self, bb, fresh, params):
        if fresh:
            bb.spiral_theta, bb.spiral_radius = 0.0, 0.0
        bb.spiral_on = True
        bb.spiral_params = (self.radius(params), self.velocity(params), self.pitch(params))
        bb.spiral_axes = self.axes

    def rows(self, board, rows, fresh, params):
        board.spiral_theta[rows[fresh]] = 0.0
        board.spiral_radius[rows[fresh]] = 0.0
        board.spiral_on[rows] = True
        board.spiral_params[rows] = np.stack([self.radius.rows(params), self.velocity.rows(params),
                                              self.pitch.rows(params)], axis=-1)
        board.set_spiral_axes(rows, self.axes)


@LEAF_PROGRAMS.register
def _set_goal_from_object(i: int, leaf, ctx: _Context):
    index, slot_of, nominal_pos, nominal_quat = ctx.index, ctx.slot_of, ctx.nominal_pos, ctx.nominal_quat
    obj = leaf.args.get("object")
    if obj not in slot_of:
        raise ValueError(f"leaf {quote(leaf.name)}: object {quote(obj)} is not bound to the scene")
    base = np.asarray(nominal_pos[slot_of[obj]], float) + np.asarray(leaf.args.get("offset", (0.0, 0.0, 0.0)), float)
    dx, dy = _input(leaf, "offset_x", index), _input(leaf, "offset_y", index)
    roll, pitch, yaw = (_input(leaf, f"tool_{k}", index) for k in ("roll", "pitch", "yaw"))
    tilted = any(f"tool_{k}" in leaf.args or f"tool_{k}" in leaf.params for k in ("roll", "pitch"))
    w, x, y, z = nominal_quat[slot_of[obj]]
    object_yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    aligned = goal_orientation(leaf) == "tool_down_aligned"
    return Always(Status.SUCCESS), SetGoal(base, dx, dy, yaw, roll, pitch, tilted, object_yaw, aligned)


@LEAF_PROGRAMS.register
def _goal_pose(i: int, leaf, ctx: _Context):
    return _running, StartMotion()


@LEAF_PROGRAMS.register
def _change_stiffness(i: int, leaf, ctx: _Context):
    return _running, SetStiffness(np.asarray(leaf.args["stiffness"], float))


@LEAF_PROGRAMS.register
def _apply_force(i: int, leaf, ctx: _Context):
    base, sources = force_inputs(leaf, ctx.index)
    return _running, ApplyForce(base, [(axis, _Reader(source)) for axis, source in sources])


@LEAF_PROGRAMS.register
def _overlay_spiral(i: int, leaf, ctx: _Context):
    radius, velocity, pitch = (_Reader(source) for source in spiral_inputs(leaf, ctx.index))
    return _running, OverlaySpiral(radius, velocity, pitch, plane_basis(leaf.args.get("normal", SPIRAL_NORMAL)))


@LEAF_PROGRAMS.register
def _ee_pose_distance(i: int, leaf, ctx: _Context):
    return Reached(float(leaf.args["threshold"])), _keep


@LEAF_PROGRAMS.register
def _wait(i: int, leaf, ctx: _Context):
    return Waited(i, wait_ticks(leaf, ctx.tick_seconds)), _keep
