"""Where the MJCF scenes live and how to load them (host side, native MuJoCo)."""

from __future__ import annotations

from pathlib import Path

import mujoco

# assets/ sits next to the package in the source tree (pyproject ships *.xml as package data
# only inside packages, so an installed copy must run from a checkout: README, "Using the library").
ASSETS_DIR = Path(__file__).resolve().parents[2] / "assets"
SCENES = ("push", "peg")

ARM_JOINTS = tuple(f"joint{i}" for i in range(1, 8))
TOOL_SITE = "tool"
# The push scene: object centroid height when resting on the table (prism 0.07 m high).
PUSH_OBJECT_BODY = "object"
PUSH_GOAL_BODY = "goal"
# Peg scene: mocap body of the box with the hole; the hole's top above the box frame.
PEG_BOX_BODY = "box"
HOLE_TOP = 0.05
HOLE_DEPTH = 0.04
HOLE_CLEARANCE = 0.0015


def scene_path(name: str) -> Path:
    """Path of ``assets/<name>.xml``; ``name`` is one of :data:`SCENES`."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; expected one of {SCENES}")
    return ASSETS_DIR / f"{name}.xml"


def load_scene(name: str) -> mujoco.MjModel:
    """Native MjModel of scene ``name`` ('push' or 'peg')."""
    return mujoco.MjModel.from_xml_path(str(scene_path(name)))


def arm_qpos_addresses(model: mujoco.MjModel) -> tuple[int, ...]:
    """qpos addresses of joint1..joint7 (the arm is first in every scene: 0..6)."""
    return tuple(int(model.jnt_qposadr[model.joint(name).id]) for name in ARM_JOINTS)
