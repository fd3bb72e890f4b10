"""The leaf primitives of the eBT: the vocabulary both engines implement.

A leaf's ``Node.primitive`` names one of ``PRIMITIVES``; the compiled rollout
(``mjxskill.rollout.leaves``) and the native engine (``mjxskill.native.leaves``) each keep one
registry of leaf programs keyed by these names, and a test checks that both registries name
exactly this tuple.

"Holds" leaves keep their effect in force while they are ticked and return RUNNING; a ParallelFs
ends when its distance check succeeds, which halts them.

``set_goal_from_object`` (SUCCESS at once): writes the motion goal = position of ``args.object``
    (scenario object name; ``args.mjcf_body`` its MJCF body or None for a pose without one, whose
    position comes from the scenario) + ``args.offset`` (3,) m world frame + the values of
    ``params.offset_x`` / ``params.offset_y``; orientation (tool z along world -z):
    ``args.orientation`` = "tool_down_aligned" (the square tool's faces turned to the element's
    yaw) or "tool_down" (the tool's yaw kept, so the move is a pure translation).
``goal_pose`` (holds, RUNNING): the motion generator drives the reference toward the goal.
``change_stiffness`` (holds, RUNNING): ``args.stiffness`` (6,) N/m x3, Nm/rad x3.
``apply_force`` (holds, RUNNING): ``args.wrench`` (6,) N, Nm in the world frame; a component named
    in ``params`` (``force_x``, ``force_y``, ``force_z``) is replaced by that parameter's value.
``overlay_spiral`` (holds, RUNNING): Archimedes spiral on the reference in the xy plane;
    ``params.radius`` (m, cap), ``params.path_velocity`` (m/s), ``params.pitch`` (m per turn).
``ee_pose_distance``: RUNNING until the tool is within ``args.threshold`` m of the goal, then
    SUCCESS.
``wait``: RUNNING until ``args.seconds`` have passed since its first tick, then SUCCESS.

A leaf input comes from ``params`` (the name of a learnable parameter, looked up in the parameter
vector) when named there, otherwise from ``args`` (a fixed value): a skill parameter the world
model does not mark learnable is written into ``args`` under the input's name.
"""

from __future__ import annotations

import numpy as np

PRIMITIVES = (
    "set_goal_from_object",
    "goal_pose",
    "change_stiffness",
    "apply_force",
    "overlay_spiral",
    "ee_pose_distance",
    "wait",
)

ORIENTATIONS = ("tool_down_aligned", "tool_down")  # set_goal_from_object's ``args.orientation``
SPIRAL_NORMAL = np.array([0.0, 0.0, 1.0], np.float32)  # overlay_spiral's search plane is horizontal


def goal_orientation(leaf) -> str:
    """ElementToBBPose's ``args.orientation``: "tool_down_aligned" (default) turns the tool's
    faces to the element's yaw; "tool_down" keeps the tool's current yaw (a pure translation)."""
    orientation = leaf.args.get("orientation", "tool_down_aligned")
    if orientation not in ORIENTATIONS:
        raise ValueError(f"leaf {leaf.name!r}: orientation {orientation!r} is not one of {', '.join(ORIENTATIONS)}")
    return orientation


class LeafRegistry(dict):
    """One engine's leaf programs: primitive name -> builder ``(leaf number, leaf, context) ->
    (status, effect)``. ``@registry.register`` adds a builder under its function's name without
    the leading underscore (``_goal_pose`` -> "goal_pose")."""

    def register(self, builder):
        name = builder.__name__.lstrip("_")
        if name not in PRIMITIVES:
            raise ValueError(f"{name!r} is not a leaf primitive ({', '.join(PRIMITIVES)})")
        self[name] = builder
        return builder

    def build(self, i: int, leaf, context):
        """(status, effect) of leaf number ``i``."""
        builder = self.get(leaf.primitive)
        if builder is None:
            raise ValueError(f"leaf {leaf.name!r}: no leaf program for primitive {leaf.primitive!r}")
        return builder(i, leaf, context)


__all__ = ["ORIENTATIONS", "PRIMITIVES", "SPIRAL_NORMAL", "LeafRegistry", "goal_orientation"]
