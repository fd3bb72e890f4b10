"""The blackboard a native episode's leaf programs share, one episode's (fields as
``mjxskill.engine.mjx.leaves.Blackboard``): the plain loop's and the numpy lockstep's. A
batch's rows hold the same fields as arrays (``mjxskill.engine.native.board.RowsBoard``)."""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from mjxskill.ebt.primitives import SPIRAL_NORMAL
from mjxskill.engine.native.kernels import spiral_rows
from mjxskill.engine.native.motion import LinearMotion, plane_basis, references_at, spiral_step


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
            pos = spiralled(pos, self.spiral_radius, self.spiral_theta, *self.spiral_axes)
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

    def remember_end(self, pos: np.ndarray, quat: np.ndarray) -> None:
        """The reference (3,), (4,) at the time the blackboard has been advanced to (computed
        with the tick's references), kept as ``reference()``'s value until the blackboard changes."""
        self.end_reference = (self._reference_key(), pos, quat)

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


def spiralled(pos: np.ndarray, radius: float, theta: float, e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
    """A reference position (3,) with the search spiral's offset at ``radius`` and ``theta`` in
    the plane of the unit vectors ``e1``, ``e2`` (3,) (``kernels.spiral_rows`` computes the same
    operations for a tick's rows)."""
    return pos + radius * (math.cos(theta) * e1 + math.sin(theta) * e2)


def references_rows(bbs: list[NativeBlackboard], n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The references of the next ``n`` control periods of N blackboards: positions (n, N, 3) and
    quaternions (n, N, 4), the blackboards advanced past them; every motion evaluated in one
    compiled pass over (n + 1, N) times (``motion.references_at``: the last is the reference at
    the end, which ``reference()`` then returns), the spirals in another (``kernels.spiral_rows``).
    A row's values do not depend on the other rows."""
    start = np.array([bb.mg_time for bb in bbs])
    # sequential sums down each column, as a blackboard's own cumsum and += dt
    times = np.cumsum(np.concatenate([start[None], np.full((n, len(bbs)), dt)]), axis=0)
    pos, quat = references_at(np.stack([bb.motion.row for bb in bbs]), times)
    end_pos, end_quat = pos[-1].copy(), quat[-1]
    pos, quat = pos[:-1], quat[:-1]
    on = np.array([bb.spiral_on for bb in bbs])
    if on.any():
        spirals = [bb for bb in bbs if bb.spiral_on]
        theta, radius = np.array([bb.spiral_theta for bb in spirals]), np.array([bb.spiral_radius for bb in spirals])
        spiral_pos, spiral_end = np.ascontiguousarray(pos[:, on]), end_pos[on]
        spiral_rows(theta, radius, np.array([bb.spiral_params for bb in spirals], float),
                    np.array([np.stack(bb.spiral_axes) for bb in spirals]), dt, spiral_pos, spiral_end)
        pos[:, on], end_pos[on] = spiral_pos, spiral_end
        for bb, th, rad in zip(spirals, theta.tolist(), radius.tolist()):
            bb.spiral_theta, bb.spiral_radius = th, rad
    for r, bb in enumerate(bbs):
        bb.mg_time = float(times[-1, r])
        bb.remember_end(end_pos[r], end_quat[r])
    return pos, quat
