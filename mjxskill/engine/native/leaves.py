"""The leaf programs of ``mjxskill.engine.mjx.leaves`` in plain Python over a mutable blackboard, for
the native-MuJoCo baseline (same two phases per BT tick: every leaf's status from the state
before the tick, then the effects of the leaves the tick activated, in tick order).
"""

from __future__ import annotations

import math
from typing import Callable, NamedTuple

import numpy as np

from mjxskill.ebt.nodes import Node, Status
from mjxskill.ebt.primitives import SPIRAL_NORMAL, LeafRegistry, goal_orientation
from mjxskill.engine.common.arrays import HOST
from mjxskill.engine.common.leaf_inputs import LeafInput, force_inputs, leaf_input, spiral_inputs, wait_ticks
from mjxskill.engine.common.rotations import quat_mul
from mjxskill.engine.common.tool import TOOL_DOWN, TOOL_SYMMETRY, tool_yaw
from mjxskill.engine.native.kernels import spiral_offsets
from mjxskill.engine.native.motion import LinearMotion, plane_basis, references_at, spiral_step
from mjxskill.errors import quote


class NativeBlackboard:
    """Per-episode state the leaf programs share (fields as ``rollout.leaves.Blackboard``).

    goal_pos (3,), goal_quat (4,); motion: the current LinearMotion; mg_time s; stiffness (6,),
    wrench (6,); spiral_theta, spiral_radius, spiral_on, spiral_params (radius cap, velocity,
    pitch), spiral_axes (two (3,) unit vectors spanning its plane); leaf_ticks: list of L ints.
    """

    _goal_quat: np.ndarray | None  # None: ``_goal_quat_of()`` computes it when read
    _goal_quat_of: Callable[[], np.ndarray] | None

    def __init__(self, tool_pos, tool_quat, default_stiffness, n_leaves: int):
        self.goal_pos = np.array(tool_pos, float)
        self.goal_quat = np.array(tool_quat, float)
        self.motion = LinearMotion(tool_pos, tool_quat, tool_pos, tool_quat)
        self.mg_time = 0.0
        self.stiffness = np.array(default_stiffness, float)
        self.wrench = np.zeros(6)
        self.spiral_theta = 0.0
        self.spiral_radius = 0.0
        self.spiral_on = False
        self.spiral_params = (0.0, 0.0, 0.0)
        self.spiral_axes = plane_basis(SPIRAL_NORMAL)
        self.leaf_ticks = [0] * n_leaves
        # The reference at the end of the last ``references``, with what it was computed from
        # (motion, time, spiral state): the tick's rewards and the next tick's goals ask for it.
        self.end_reference: tuple | None = None

    def copy(self) -> "NativeBlackboard":
        # Fields are rebound, never mutated in place, so a shallow copy is a snapshot (made as
        # ``copy.copy`` makes it, without its protocol's cost: this runs every tick and episode).
        new = object.__new__(NativeBlackboard)
        new.__dict__.update(self.__dict__)
        new.leaf_ticks = list(self.leaf_ticks)
        return new

    @property
    def goal_quat(self) -> np.ndarray:
        """The goal orientation (4,): set, or computed from what a goal leaf deferred
        (``defer_goal_quat``) when first read, i.e. when a motion starts towards it."""
        if self._goal_quat is None:
            assert self._goal_quat_of is not None  # set together: one of the two is None
            self._goal_quat = self._goal_quat_of()
        return self._goal_quat

    @goal_quat.setter
    def goal_quat(self, quat: np.ndarray) -> None:
        self._goal_quat, self._goal_quat_of = quat, None

    def defer_goal_quat(self, compute: Callable[[], np.ndarray]) -> None:
        """The goal orientation is ``compute()``, a pure function, called when it is read: a goal
        leaf runs every tick its sequence is ticked, and a moving reference makes its value
        new each time, but only a starting motion reads it."""
        self._goal_quat, self._goal_quat_of = None, compute

    def reference(self) -> tuple[np.ndarray, np.ndarray]:
        """Controller reference position (3,) and quaternion (4,)."""
        end = self.end_reference
        if end is not None and self._same_reference(end[0]):
            return end[1].copy(), end[2].copy()
        pos, quat = self.motion.at(self.mg_time)
        return self._spiralled(pos), quat

    def _spiralled(self, pos: np.ndarray) -> np.ndarray:
        """A motion's reference position (3,) with the spiral's offset now, if it is on."""
        if self.spiral_on:
            r, th = self.spiral_radius, self.spiral_theta
            e1, e2 = self.spiral_axes
            pos = pos + r * (math.cos(th) * e1 + math.sin(th) * e2)
        return pos

    def _reference_key(self) -> tuple:
        """What the reference depends on besides constants: the motion (a started motion is a
        new object), its time and the spiral's state (its angle, radius and plane)."""
        return (self.motion, self.mg_time, self.spiral_on, self.spiral_theta, self.spiral_radius, self.spiral_axes)

    def _same_reference(self, key: tuple) -> bool:
        motion, time, spiral_on, theta, radius, axes = key
        if motion is not self.motion or time != self.mg_time or spiral_on != self.spiral_on:
            return False
        return not spiral_on or (theta == self.spiral_theta and radius == self.spiral_radius and axes is self.spiral_axes)

    def remember_end(self, motion_pos: np.ndarray, motion_quat: np.ndarray) -> None:
        """The motion's reference (3,), (4,) at the time it has been advanced to (computed with
        the tick's references), kept as ``reference()``'s value until the blackboard changes."""
        self.end_reference = (self._reference_key(), self._spiralled(motion_pos), motion_quat)

    def references(self, n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The references of the next ``n`` control periods, positions (n, 3) and quaternions
        (n, 4), and the blackboard advanced past them: what ``n`` rounds of ``reference()`` and
        ``advance(dt)`` give (to rounding), as ``references_rows`` gives them for one row."""
        pos, quat = references_rows([self], n, dt)
        return pos[:, 0], quat[:, 0]

    def advance(self, dt: float) -> None:
        """One control period of the motion generator and the spiral."""
        self.mg_time += dt
        if self.spiral_on:
            radius_max, velocity, pitch = self.spiral_params
            self.spiral_theta, self.spiral_radius = spiral_step(
                self.spiral_theta, self.spiral_radius, radius_max, velocity, pitch, dt
            )


def references_rows(bbs: list[NativeBlackboard], n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The references of the next ``n`` control periods of N blackboards: positions (n, N, 3) and
    quaternions (n, N, 4), the blackboards advanced past them; every motion evaluated in one
    compiled pass over (n + 1, N) times (``motion.references_at``: the last is the reference at
    the end, which ``reference()`` then returns); the spirals, on few rows, row by row. A row's
    values do not depend on the other rows."""
    start = np.array([bb.mg_time for bb in bbs])
    # sequential sums down each column, as a blackboard's own cumsum and += dt
    times = np.cumsum(np.concatenate([start[None], np.full((n, len(bbs)), dt)]), axis=0)
    pos, quat = references_at(np.stack([bb.motion.row for bb in bbs]), times)
    end_pos, end_quat = pos[-1], quat[-1]
    pos, quat = pos[:-1], quat[:-1]
    for r, bb in enumerate(bbs):
        bb.mg_time = float(times[-1, r])
        if bb.spiral_on:
            radius_max, velocity, pitch = bb.spiral_params
            e1, e2 = bb.spiral_axes
            offsets, bb.spiral_theta, bb.spiral_radius = spiral_offsets(
                bb.spiral_theta, bb.spiral_radius, radius_max, velocity, pitch, dt, e1, e2, n)
            pos[:, r] = pos[:, r] + offsets
        bb.remember_end(end_pos[r], end_quat[r])
    return pos, quat


class LeafStatus:
    """A leaf's status from the state before the tick: called with one blackboard, the tool
    position (3,) and whether the leaf runs on from the last tick; ``rows(bbs, tool_pos, live)``
    for m blackboards at once, tool positions (m, 3) and live (m,) bool, as
    (m,) int Status values (what a batch's compiled tree ticks on, ``bt_compiled.tick_rows``)."""

    def __call__(self, bb: NativeBlackboard, tool_pos: np.ndarray, live: bool) -> Status:
        raise NotImplementedError

    def rows(self, bbs: list[NativeBlackboard], tool_pos: np.ndarray, live: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class Always(LeafStatus):
    """The same status every tick."""

    def __init__(self, status: Status):
        self.status = status

    def __call__(self, bb, tool_pos, live):
        return self.status

    def rows(self, bbs, tool_pos, live):
        return np.full(len(bbs), int(self.status))


class Reached(LeafStatus):
    """SUCCESS once the tool is within ``threshold`` (m) of the running motion's goal, on a tick
    after the leaf's first (its first tick starts the motion it waits for)."""

    def __init__(self, threshold: float):
        self.threshold = threshold

    def __call__(self, bb, tool_pos, live):
        close = HOST.linalg.norm(tool_pos - bb.motion.goal_pos) < self.threshold
        return Status.SUCCESS if live and close else Status.RUNNING

    def rows(self, bbs, tool_pos, live):
        close = HOST.linalg.norm(tool_pos - np.stack([bb.motion.goal_pos for bb in bbs]), axis=-1) < self.threshold
        return np.where(live & close, int(Status.SUCCESS), int(Status.RUNNING))


class Waited(LeafStatus):
    """SUCCESS once leaf ``leaf`` has been ticked ``ticks`` times in a row."""

    def __init__(self, leaf: int, ticks: int):
        self.leaf, self.ticks = leaf, ticks

    def __call__(self, bb, tool_pos, live):
        return Status.SUCCESS if live and bb.leaf_ticks[self.leaf] >= self.ticks else Status.RUNNING

    def rows(self, bbs, tool_pos, live):
        waited = np.array([bb.leaf_ticks[self.leaf] for bb in bbs]) >= self.ticks
        return np.where(live & waited, int(Status.SUCCESS), int(Status.RUNNING))


# effect(bb, fresh, params) -> None (writes bb).
EffectFn = Callable[[NativeBlackboard, bool, np.ndarray], None]
_running = Always(Status.RUNNING)


def _input(leaf: Node, name: str, index: dict) -> Callable[[np.ndarray], float]:
    """A leaf input as a function of the parameter vector (``leaf_inputs.leaf_input``)."""
    return _reader(leaf_input(leaf, name, index))


def _reader(source: LeafInput) -> Callable[[np.ndarray], float]:
    if source.index is not None:
        return lambda params: float(params[source.index])
    return lambda params: source.value


def _keep(bb, fresh, params):
    return None


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
                        nominal_quat: np.ndarray, tick_seconds: float) -> list[tuple[LeafStatus, EffectFn]]:
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

    def goal_quat(current: np.ndarray, params: np.ndarray) -> np.ndarray:
        target = (object_yaw if aligned else tool_yaw(current)) + math.radians(yaw(params))
        tilt = (math.radians(roll(params)), math.radians(pitch(params))) if tilted else None
        return tool_down_aligned(current, target, tilt)

    def set_goal(bb, fresh, params):
        bb.goal_pos = base + np.array([dx(params), dy(params), 0.0])
        current = bb.reference()[1]
        bb.defer_goal_quat(lambda: goal_quat(current, params))

    return Always(Status.SUCCESS), set_goal


@LEAF_PROGRAMS.register
def _goal_pose(i: int, leaf, ctx: _Context):

    def start_motion(bb, fresh, params):
        if fresh:
            pos, quat = bb.reference()
            bb.motion = LinearMotion(pos, quat, bb.goal_pos, bb.goal_quat)
            bb.mg_time = 0.0

    return _running, start_motion


@LEAF_PROGRAMS.register
def _change_stiffness(i: int, leaf, ctx: _Context):
    stiffness = np.asarray(leaf.args["stiffness"], float)

    def set_stiffness(bb, fresh, params):
        bb.stiffness = stiffness

    return _running, set_stiffness


@LEAF_PROGRAMS.register
def _apply_force(i: int, leaf, ctx: _Context):
    index = ctx.index
    base, sources = force_inputs(leaf, index)
    overrides = [(axis, _reader(source)) for axis, source in sources]

    def apply_force(bb, fresh, params):
        wrench = base.copy()
        for axis, value in overrides:
            wrench[axis] = value(params)
        bb.wrench = wrench

    return _running, apply_force


@LEAF_PROGRAMS.register
def _overlay_spiral(i: int, leaf, ctx: _Context):
    radius, velocity, pitch = (_reader(source) for source in spiral_inputs(leaf, ctx.index))
    axes = plane_basis(leaf.args.get("normal", SPIRAL_NORMAL))

    def overlay(bb, fresh, params):
        if fresh:
            bb.spiral_theta, bb.spiral_radius = 0.0, 0.0
        bb.spiral_on = True
        bb.spiral_params = (radius(params), velocity(params), pitch(params))
        bb.spiral_axes = axes

    return _running, overlay


@LEAF_PROGRAMS.register
def _ee_pose_distance(i: int, leaf, ctx: _Context):
    return Reached(float(leaf.args["threshold"])), _keep


@LEAF_PROGRAMS.register
def _wait(i: int, leaf, ctx: _Context):
    return Waited(i, wait_ticks(leaf, ctx.tick_seconds)), _keep
