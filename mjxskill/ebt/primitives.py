"""The leaf primitives of the eBT: the vocabulary both engines implement.

A leaf's ``Node.primitive`` names one of ``PRIMITIVES``; the compiled rollout
(``mjxskill.engine.mjx.leaves``) and the native engine (``mjxskill.engine.native.leaves``) each keep one
registry of leaf programs keyed by these names, and a test checks that both registries name
exactly this tuple.

"Holds" leaves keep their effect in force while they are ticked and return RUNNING; a ParallelFs
ends when its distance check succeeds, which halts them.

``set_goal_from_object`` (SUCCESS at once): writes the motion goal = position of ``object``
    (a scenario object; its MJCF body is written beside it as ``mjcf_body`` for the reader of
    the tree) + ``offset`` (3,) m world frame + ``offset_x`` / ``offset_y`` m. The tool's
    orientation: pointing down (its z along world -z), turned about world z by ``orientation``
    = "tool_down_aligned" (the square tool's faces turned to the object's yaw) or "tool_down"
    (the tool's current yaw kept, so the move is a pure translation), plus ``tool_yaw`` deg, and
    tilted by ``tool_roll`` / ``tool_pitch`` deg about the axes of that turned frame (x, then
    y, world-fixed): the goal orientation is Rz(yaw + tool_yaw) Ry(tool_pitch) Rx(tool_roll)
    times the tool pointing down.
``goal_pose`` (holds, RUNNING): the motion generator drives the reference toward the goal.
``change_stiffness`` (holds, RUNNING): ``stiffness`` (6,) N/m x3, Nm/rad x3.
``apply_force`` (holds, RUNNING): ``wrench`` (6,) N, Nm in the world frame; ``force_x``,
    ``force_y``, ``force_z`` (N), when given, replace its force components.
``overlay_spiral`` (holds, RUNNING): Archimedes spiral added to the reference in the plane
    normal to ``normal`` (3,) (world frame, default z: the table's plane); ``radius`` (m,
    cap), ``path_velocity`` (m/s), ``pitch`` (m per turn).
``ee_pose_distance``: RUNNING until the tool is within ``threshold`` m of the goal, then
    SUCCESS.
``wait``: RUNNING until ``seconds`` have passed since its first tick, then SUCCESS.

A leaf input comes from ``params`` (the name of a learnable parameter, looked up in the parameter
vector at run time) when named there, otherwise from ``args`` (a fixed value) or its default
(``INPUTS``). Only the inputs marked learnable in ``INPUTS`` may name a learnable parameter; a
skill parameter the world model does not mark learnable is written into ``args``. Skills build
trees over this vocabulary in the YAML (``mjxskill.ebt.template``).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Mapping, NamedTuple

from mjxskill.errors import quote


ORIENTATIONS = ("tool_down_aligned", "tool_down")  # set_goal_from_object's ``args.orientation``
SPIRAL_NORMAL = (0.0, 0.0, 1.0)  # overlay_spiral's default ``normal``: the search plane is horizontal


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED = _Required()  # an input's default when the tree must give it


class Input(NamedTuple):
    """One input of a primitive. kind: "object" (a scenario object's name), "number", "vector3",
    "vector6" or "choice" (one of ``choices``). default: its value when the tree gives none
    (``REQUIRED``: it must give one; None: the leaf does without it). learnable: the input may
    name a learnable parameter (the leaf program reads it from the parameter vector at run
    time). unit: for the reader."""

    kind: str
    default: object = REQUIRED
    learnable: bool = False
    choices: tuple[str, ...] = ()
    unit: str = ""


_ZERO = Input("number", 0.0, learnable=True)

# primitive -> input name -> Input: what a skill's tree may give each leaf (the template reader,
# mjxskill.scenario.skill_tree, checks every leaf against it; the leaf programs read the same
# names and defaults).
INPUTS: Mapping[str, Mapping[str, Input]] = MappingProxyType({
    "set_goal_from_object": MappingProxyType({
        "object": Input("object", REQUIRED),
        "offset": Input("vector3", (0.0, 0.0, 0.0), unit="m"),
        "orientation": Input("choice", "tool_down_aligned", choices=ORIENTATIONS),
        "offset_x": _ZERO._replace(unit="m"), "offset_y": _ZERO._replace(unit="m"),
        "tool_roll": _ZERO._replace(unit="deg"), "tool_pitch": _ZERO._replace(unit="deg"),
        "tool_yaw": _ZERO._replace(unit="deg"),
    }),
    "goal_pose": MappingProxyType({}),
    "change_stiffness": MappingProxyType({"stiffness": Input("vector6", REQUIRED, unit="N/m, Nm/rad")}),
    "apply_force": MappingProxyType({
        "wrench": Input("vector6", (0.0,) * 6, unit="N, Nm"),
        **{f"force_{c}": Input("number", None, learnable=True, unit="N") for c in "xyz"},
    }),
    "overlay_spiral": MappingProxyType({
        "radius": _ZERO._replace(unit="m"), "path_velocity": _ZERO._replace(unit="m/s"),
        "pitch": _ZERO._replace(unit="m"), "normal": Input("vector3", SPIRAL_NORMAL),
    }),
    "ee_pose_distance": MappingProxyType({"threshold": Input("number", REQUIRED, unit="m")}),
    "wait": MappingProxyType({"seconds": Input("number", REQUIRED, unit="s")}),
})


PRIMITIVES = tuple(INPUTS)


def goal_orientation(leaf) -> str:
    """ElementToBBPose's ``args.orientation``: "tool_down_aligned" (default) turns the tool's
    faces to the element's yaw; "tool_down" keeps the tool's current yaw (a pure translation)."""
    orientation = leaf.args.get("orientation", "tool_down_aligned")
    if orientation not in ORIENTATIONS:
        raise ValueError(f"leaf {quote(leaf.name)}: orientation {quote(orientation)} is not one of {', '.join(ORIENTATIONS)}")
    return orientation


class LeafRegistry(dict):
    """One engine's leaf programs: primitive name -> builder ``(leaf number, leaf, context) ->
    (status, effect)``. ``@registry.register`` adds a builder under its function's name without
    the leading underscore (``_goal_pose`` -> "goal_pose")."""

    def register(self, builder):
        name = builder.__name__.lstrip("_")
        if name not in PRIMITIVES:
            raise ValueError(f"{quote(name)} is not a leaf primitive ({', '.join(PRIMITIVES)})")
        self[name] = builder
        return builder

    def build(self, i: int, leaf, context):
        """(status, effect) of leaf number ``i``."""
        builder = self.get(leaf.primitive)
        if builder is None:
            raise ValueError(f"leaf {quote(leaf.name)}: no leaf program for primitive {quote(leaf.primitive)}")
        return builder(i, leaf, context)


__all__ = ["INPUTS", "ORIENTATIONS", "PRIMITIVES", "REQUIRED", "SPIRAL_NORMAL", "Input", "LeafRegistry", "goal_orientation"]
