"""The world model's shapes in the simulator: each shape of ``mjxskill.scenario.vocabulary.SHAPES``
knows its inertia (closed form, uniform density) and how its sizes are written into the MJCF
geoms that draw it (``mjxskill.sim.model.build_model`` calls these on an ``mujoco.MjSpec``).

A shape is drawn by the geoms of its object's body, in the shape's frame:

* ``box``: the body's one box geom; its frame is the geom's. A resized box keeps the face
  nearest its body's origin where it was (a tool stays mounted on its flange; a free box whose
  origin is its centre keeps its centre).
* ``right_triangle_prism``: the body's one mesh geom of six vertices, placed at the body origin
  (the triangle's centroid at half height); resizing rewrites the vertices.
* ``box_with_hole``: five box geoms (four walls, a bottom) in the body frame, origin at the bottom
  centre; all five are rewritten from the outer size, the hole's depth and its clearance.
* ``pose``: nothing to draw, no inertia.

The inertia is the uniform solid's tensor about its centroid; an uneven weight distribution
(``com_offset``) moves the centre of mass and keeps that tensor, as the hand-written push scene
did (the distribution itself is unknown).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import mujoco
import numpy as np


class ShapeError(ValueError):
    """What the MJCF does not let a shape be drawn as the YAML says: (YAML key, message)."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key


class Drawn(NamedTuple):
    """The MJCF side of one object: its body (``mujoco.MjsBody``), that body's geoms in file order
    and their compiled poses in the body frame (pos (G, 3), rotation (G, 3, 3)). hole_item: (2,) m,
    the width and depth (x, y) of the item the robot holds (a hole's clearance is relative to
    it), or None."""

    body: object
    geoms: list
    geom_pos: np.ndarray
    geom_rot: np.ndarray
    hole_item: np.ndarray | None


class ShapeModel(NamedTuple):
    """inertia(size, extra, drawn) -> (centroid (3,) in the body frame, tensor (3, 3) per kg about
    it in the body frame); draw(size, extra, drawn, spec) writes the sizes into the geoms (and
    meshes) of ``spec`` (raises ShapeError). None: the shape has neither."""

    inertia: Callable | None
    draw: Callable | None


def box_tensor(size) -> np.ndarray:
    """(3, 3) inertia per kg of a uniform box with edge lengths ``size`` (3,) about its centre."""
    a, b, c = (float(v) for v in size)
    return np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) / 12.0


def prism_tensor(size) -> np.ndarray:
    """(3, 3) inertia per kg of a uniform right-triangle prism, legs a (x) and b (y) from the
    right angle toward +x and +y, height h (z), about its centroid (products included:
    the product integral of the triangle about its centroid is -a b / 36 per unit mass)."""
    a, b, h = (float(v) for v in size)
    ixy = a * b / 36.0  # MuJoCo's M(1, 2) = -integral of x y dm
    return np.array([[b * b / 18.0 + h * h / 12.0, ixy, 0.0],
                     [ixy, a * a / 18.0 + h * h / 12.0, 0.0],
                     [0.0, 0.0, (a * a + b * b) / 18.0]])


def prism_vertices(size) -> np.ndarray:
    """(6, 3) vertices of the prism with its centroid at the origin (bottom triangle, then top)."""
    a, b, h = (float(v) for v in size)
    corners = np.array([[-a / 3, -b / 3], [2 * a / 3, -b / 3], [-a / 3, 2 * b / 3]])
    return np.array([[x, y, z] for z in (-h / 2, h / 2) for x, y in corners])


def _one_geom(drawn: Drawn, shape: str, kind) -> int:
    if len(drawn.geoms) != 1 or drawn.geoms[0].type != kind:
        found = ", ".join(f"{g.name or '?'} ({g.type.name.removeprefix('mjGEOM_').lower()})" for g in drawn.geoms) or "none"
        raise ShapeError("shape", f"a {shape} is drawn by exactly one {kind.name.removeprefix('mjGEOM_').lower()} geom "
                                  f"of body {drawn.body.name!r}; it has {found}")
    return 0


# -- box ----------------------------------------------------------------------------------------
def _box_inertia(size, extra, drawn: Drawn):
    i = _one_geom(drawn, "box", mujoco.mjtGeom.mjGEOM_BOX)
    rot = drawn.geom_rot[i]
    return drawn.geom_pos[i].copy(), rot @ box_tensor(size) @ rot.T


def _box_draw(size, extra, drawn: Drawn, spec):
    i = _one_geom(drawn, "box", mujoco.mjtGeom.mjGEOM_BOX)
    geom = drawn.geoms[i]
    half, old = np.asarray(size, float) / 2, np.array(geom.size[:3], float)
    pos = np.array(geom.pos, float)
    if np.allclose(drawn.geom_rot[i], np.eye(3)):
        # keep the face nearest the body origin: a mounted tool stays on its flange
        side = np.sign(pos)
        pos = pos - side * old + side * half
    geom.size = half
    geom.pos = pos


# -- right-triangle prism -----------------------------------------------------------------------
def _prism_geom(drawn: Drawn) -> int:
    i = _one_geom(drawn, "right_triangle_prism", mujoco.mjtGeom.mjGEOM_MESH)
    geom = drawn.geoms[i]
    if np.any(np.array(geom.pos) != 0) or np.any(np.array(geom.quat) != [1, 0, 0, 0]) or \
            geom.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:
        raise ShapeError("shape", f"the prism's mesh geom {geom.name!r} must sit at its body's origin, unrotated "
                                  f"(the body origin is the prism's centroid)")
    return i


def _prism_inertia(size, extra, drawn: Drawn):
    _prism_geom(drawn)
    return np.zeros(3), prism_tensor(size)


def _prism_draw(size, extra, drawn: Drawn, spec):
    geom = drawn.geoms[_prism_geom(drawn)]
    mesh = spec.mesh(geom.meshname)
    if len(mesh.uservert) != 18:
        raise ShapeError("shape", f"the prism's mesh {geom.meshname!r} has {len(mesh.uservert) // 3} vertices, not 6")
    mesh.uservert = prism_vertices(size).ravel().tolist()


# -- box with a hole ----------------------------------------------------------------------------
def hole_half_widths(extra, hole_item) -> np.ndarray:
    """(2,) m: the hole's half-widths, those of the held item (``hole_item`` (2,) m: its x-y
    size, or None) plus the clearance."""
    if hole_item is None:
        raise ShapeError("extra.hole_clearance", "the hole's clearance is relative to the item the robot holds "
                                                 "(a (holding ...) relation to an object of shape box): there is none")
    return np.asarray(hole_item, float) / 2 + float(extra["hole_clearance"])


def box_with_hole_parts(size, extra, drawn: Drawn) -> list[tuple[np.ndarray, np.ndarray]]:
    """(centre (3,), half size (3,)) of the walls +x, -x, +y, -y and the bottom, body frame."""
    ax, ay, c = np.asarray(size, float) / [2, 2, 1]
    hx, hy = hole_half_widths(extra, drawn.hole_item)
    depth = float(extra["hole_depth"])
    if not (hx < ax and hy < ay and depth < c):
        raise ShapeError("size", f"the hole ({2 * hx:.4g} x {2 * hy:.4g} m, {depth:g} m deep) does not fit in the box "
                                 f"({2 * ax:g} x {2 * ay:g} x {c:g} m)")
    zc, dz = c - depth / 2, depth / 2
    walls = [(np.array([s * (ax + hx) / 2, 0, zc]), np.array([(ax - hx) / 2, ay, dz])) for s in (1, -1)]
    walls += [(np.array([0, s * (ay + hy) / 2, zc]), np.array([hx, (ay - hy) / 2, dz])) for s in (1, -1)]
    bottom = (np.array([0, 0, (c - depth) / 2]), np.array([ax, ay, (c - depth) / 2]))
    return walls + [bottom]


def _box_with_hole_inertia(size, extra, drawn: Drawn):
    parts = box_with_hole_parts(size, extra, drawn)
    volumes = np.array([np.prod(2 * half) for _, half in parts])
    masses = volumes / volumes.sum()
    centroid = sum(m * c for m, (c, _) in zip(masses, parts))
    tensor = np.zeros((3, 3))
    for m, (c, half) in zip(masses, parts):
        d = c - centroid
        tensor += m * (box_tensor(2 * half) + np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return centroid, tensor


def _box_with_hole_draw(size, extra, drawn: Drawn, spec):
    boxes = [i for i, g in enumerate(drawn.geoms) if g.type == mujoco.mjtGeom.mjGEOM_BOX]
    if len(boxes) != 5 or len(drawn.geoms) != 5 or not all(np.allclose(drawn.geom_rot[i], np.eye(3)) for i in boxes):
        raise ShapeError("shape", f"a box_with_hole is drawn by five unrotated box geoms of body {drawn.body.name!r} "
                                  f"(four walls and a bottom); it has {len(drawn.geoms)} geoms")
    pos = drawn.geom_pos
    bottom = min(boxes, key=lambda i: pos[i, 2])
    walls = [i for i in boxes if i != bottom]
    order = [max(walls, key=lambda i: pos[i, 0]), min(walls, key=lambda i: pos[i, 0]),
             max(walls, key=lambda i: pos[i, 1]), min(walls, key=lambda i: pos[i, 1])]
    if len(set(order)) != 4:
        raise ShapeError("shape", f"the walls of body {drawn.body.name!r} are not one on each side of the hole")
    for i, (centre, half) in zip(order + [bottom], box_with_hole_parts(size, extra, drawn)):
        drawn.geoms[i].pos = centre
        drawn.geoms[i].size = half


SHAPE_MODELS: dict[str, ShapeModel] = {
    "pose": ShapeModel(None, None),
    "box": ShapeModel(_box_inertia, _box_draw),
    "right_triangle_prism": ShapeModel(_prism_inertia, _prism_draw),
    "box_with_hole": ShapeModel(_box_with_hole_inertia, _box_with_hole_draw),
}


__all__ = ["SHAPE_MODELS", "Drawn", "ShapeError", "box_tensor", "box_with_hole_parts", "hole_half_widths",
           "prism_tensor", "prism_vertices"]
