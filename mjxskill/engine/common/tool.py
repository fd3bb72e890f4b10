"""The tool's orientation conventions, written once for both engines (``xp``: ``arrays.JAX`` or
``arrays.HOST``): the tool pointing down, the square tools' quarter-turn symmetry and the yaw of
a tool-down orientation."""

from __future__ import annotations

import math

import numpy as np

from mjxskill.engine.common.arrays import HOST

# Tool pointing down: rotation by pi about y (w, x, y, z), the site's z axis along world -z; its
# x axis is then world -x, so a tool turned by yaw about world z has its x axis at
# (-cos yaw, -sin yaw, 0).
TOOL_DOWN = np.array([0.0, 0.0, 1.0, 0.0])
TOOL_SYMMETRY = math.pi / 2  # both tools (pusher, peg) are square: a quarter turn maps them onto themselves


def tool_yaw(quat, xp=HOST):
    """Yaw (rad) about world z of a tool-down orientation (w, x, y, z)."""
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    return xp.arctan2(-2.0 * (x * y + w * z), -(1.0 - 2.0 * (y * y + z * z)))
