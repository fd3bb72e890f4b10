"""The blackboards of a native batch's episodes as arrays, one row per episode: what
``NativeBlackboard`` holds for one episode, read and written for many rows at once by the leaf
programs' ``rows`` forms (``mjxskill.engine.native.leaves``) and by the tick's references.

Each row's values are what its own ``NativeBlackboard`` would hold after the same ticks (the
same operations, row by row; tests/engine/native/test_batched.py compares whole episodes with
the numpy lockstep, which steps ``NativeBlackboard`` s). What happens a few times an episode (a
motion starting, a goal orientation read, a reference asked for after the blackboard changed)
is done row by row with the same scalar arithmetic as the blackboard's (its rule for when the
kept reference still holds, ``NativeBlackboard.reference``, is written here over rows).
"""

from __future__ import annotations

import numpy as np

from mjxskill.ebt.primitives import SPIRAL_NORMAL
from mjxskill.engine.native.blackboard import spiralled
from mjxskill.engine.native.kernels import spiral_rows
from mjxskill.engine.native.motion import LinearMotion, plane_basis, references_at


class RowsBoard:
    """n rows of blackboards, each from the tool's pose (n, 3), (n, 4) at its start; params
    (n, P) each row's parameters (a deferred goal orientation reads them)."""

    def __init__(self, tool_pos: np.ndarray, tool_quat: np.ndarray, default_stiffness, n_leaves: int, params):
        n = len(tool_pos)
        self.params = np.asarray(params, float)
        self.goal_pos, self.goal_quat = np.array(tool_pos, float), np.array(tool_quat, float)
        # a goal orientation not yet computed: the SetGoal effect (its number in goal_effects,
        # -1: none) and the reference orientation it was set from
        self.goal_from, self.goal_current = np.full(n, -1), np.zeros((n, 4))
        self.goal_effects: list = []
        self.motions = [LinearMotion(p, q, p, q) for p, q in zip(self.goal_pos, self.goal_quat)]
        self.motion_rows = np.stack([m.row for m in self.motions])
        self.motion_goal = np.stack([m.goal_pos for m in self.motions])
        self.motion_version = np.zeros(n, np.int64)  # a started motion is a new one
        self.mg_time = np.zeros(n)
        self.default_stiffness = np.asarray(default_stiffness, float)
        self.stiffness, self.wrench = np.tile(self.default_stiffness, (n, 1)), np.zeros((n, 6))
        self.spiral_on, self.spiral_theta, self.spiral_radius = np.zeros(n, bool), np.zeros(n), np.zeros(n)
        self.spiral_params = np.zeros((n, 3))
        self.spiral_axes = np.tile(np.stack(plane_basis(SPIRAL_NORMAL)), (n, 1, 1))
        self.axes_id = np.full(n, -1)  # which plane of axes_objects (-1: the default one)
        self.axes_objects: list[tuple[np.ndarray, np.ndarray]] = []
        self.leaf_ticks = np.zeros((n, n_leaves), np.int64)
        # the reference at the end of the last references, with what it was computed from
        self.end_pos, self.end_quat = np.zeros((n, 3)), np.zeros((n, 4))
        self.end_valid, self.end_version, self.end_time = np.zeros(n, bool), np.zeros(n, np.int64), np.zeros(n)
        self.end_spiral_on, self.end_theta, self.end_radius = np.zeros(n, bool), np.zeros(n), np.zeros(n)
        self.end_axes = np.full(n, -1)

    # -- the tick's start: held effects back to their defaults, then the active leaves' effects --
    def apply_effects(self, alive: np.ndarray, rows: np.ndarray, active: np.ndarray, started: np.ndarray,
                      effects: list) -> None:
        """The tick's effects: on the ``alive`` rows, the held effects (stiffness, wrench, spiral)
        back to their defaults; then on ``rows`` (m,), those whose trees tick, each leaf's effect
        where it is active (m, L), in leaf order, starting afresh where ``started``; every alive
        row's leaf tick counts (a row whose tree no longer ticks: all zero)."""
        self.stiffness[alive], self.wrench[alive], self.spiral_on[alive] = self.default_stiffness, 0.0, False
        for k, effect in enumerate(effects):
            on = active[:, k]
            if on.any():
                effect.rows(self, rows[on], started[on, k], self.params[rows[on]])
        ticks = np.where(active, np.where(started, 1, self.leaf_ticks[rows] + 1), 0)
        self.leaf_ticks[alive] = 0
        self.leaf_ticks[rows] = ticks

    def defer_goal_quat(self, rows: np.ndarray, effect, current: np.ndarray) -> None:
        """The goal orientation of ``rows`` is ``effect.goal_quat(current, params)``, ``current``
        (m, 4) their reference orientations now, computed when a starting motion reads it."""
        self.goal_from[rows] = _number(self.goal_effects, effect)
        self.goal_current[rows] = current

    def goal_quat_of(self, r: int) -> np.ndarray:
        """Row r's goal orientation (4,), computed now if it was deferred."""
        k = self.goal_from[r]
        if k >= 0:
            self.goal_quat[r] = self.goal_effects[k].goal_quat(self.goal_current[r].copy(), self.params[r])
            self.goal_from[r] = -1
        return self.goal_quat[r]

    def start_motion(self, r: int) -> None:
        """Row r's motion from its reference now to its goal, starting now."""
        pos, quat = self.reference(np.array([r]))
        motion = LinearMotion(pos[0], quat[0], self.goal_pos[r], self.goal_quat_of(r))
        self.motions[r] = motion
        self.motion_rows[r], self.motion_goal[r] = motion.row, motion.goal_pos
        self.mg_time[r] = 0.0
        self.motion_version[r] += 1

    def set_spiral_axes(self, rows: np.ndarray, axes: tuple[np.ndarray, np.ndarray]) -> None:
        """The spiral plane of ``rows``: ``axes``, two (3,) unit vectors (one leaf's, the same object)."""
        self.axes_id[rows] = _number(self.axes_objects, axes)
        self.spiral_axes[rows] = np.stack(axes)

    # -- the references ---------------------------------------------------------------------
    def reference(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The controller reference of ``rows`` (m,) now, positions (m, 3) and quaternions
        (m, 4): the one kept at the last tick's end where nothing it depends on has changed
        since (``NativeBlackboard.reference``'s rule), else computed as the blackboard does."""
        spiral = self.spiral_on[rows]
        kept = (self.end_valid[rows] & (self.end_version[rows] == self.motion_version[rows])
                & (self.end_time[rows] == self.mg_time[rows]) & (self.end_spiral_on[rows] == spiral))
        kept &= ~spiral | ((self.end_theta[rows] == self.spiral_theta[rows])
                           & (self.end_radius[rows] == self.spiral_radius[rows]) & (self.end_axes[rows] == self.axes_id[rows]))
        pos, quat = self.end_pos[rows].copy(), self.end_quat[rows].copy()
        for j in np.flatnonzero(~kept):
            r = int(rows[j])
            p, quat[j] = self.motions[r].at(float(self.mg_time[r]))
            if self.spiral_on[r]:
                p = spiralled(p, float(self.spiral_radius[r]), float(self.spiral_theta[r]), *self.spiral_axes[r])
            pos[j] = p
        return pos, quat

    def references(self, rows: np.ndarray, n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The references of the next ``n`` control periods of ``rows`` (m,), positions (n, m, 3)
        and quaternions (n, m, 4), and the rows advanced past them (``references_rows``' values
        for their blackboards); the reference at the end is kept for ``reference``."""
        # sequential sums down each column, as a blackboard's own cumsum and += dt
        times = np.cumsum(np.concatenate([self.mg_time[rows][None], np.full((n, len(rows)), dt)]), axis=0)
        pos, quat = references_at(self.motion_rows[rows], times)
        end_pos, end_quat = pos[-1].copy(), quat[-1].copy()
        pos, quat = pos[:-1], quat[:-1]
        self.mg_time[rows] = times[-1]
        on = self.spiral_on[rows]
        if on.any():
            spiral = rows[on]
            theta, radius = self.spiral_theta[spiral], self.spiral_radius[spiral]
            spiral_pos, spiral_end = np.ascontiguousarray(pos[:, on]), end_pos[on]
            spiral_rows(theta, radius, self.spiral_params[spiral], self.spiral_axes[spiral], dt, spiral_pos, spiral_end)
            pos[:, on], end_pos[on] = spiral_pos, spiral_end
            self.spiral_theta[spiral], self.spiral_radius[spiral] = theta, radius
        self.end_pos[rows], self.end_quat[rows], self.end_valid[rows] = end_pos, end_quat, True
        self.end_version[rows], self.end_time[rows] = self.motion_version[rows], self.mg_time[rows]
        self.end_spiral_on[rows], self.end_theta[rows] = on, self.spiral_theta[rows]
        self.end_radius[rows], self.end_axes[rows] = self.spiral_radius[rows], self.axes_id[rows]
        return pos, quat


def _number(objects: list, obj) -> int:
    """``obj``'s position in ``objects``, compared by identity (appended if it is not there): a
    row holds a number for a leaf's own object."""
    for k, known in enumerate(objects):
        if known is obj:
            return k
    objects.append(obj)
    return len(objects) - 1
