"""The world model's shapes in the simulator: each shape of ``mjxskill.scenario.vocabulary.SHAPES``
knows its inertia (closed form, uniform density) and how its sizes are written into the MJCF
geoms that draw it (``mjxskill.sim.model.build_model`` calls these on an ``mujoco.MjSpec``).

A shape is drawn by the geoms of its object's body, in the shape's frame:

* ``box``: the body's one box geom; its frame is the geom's. A resized box keeps the face
  nearest its body's origin where it was (a tool stays mounted on its flange; a free box whose
  origin is its centre keeps its centre).
* ``right_triangle_prism``: the body's one mesh geom of six vertices, placed at the body origin
  (the triangle's centroid at half height); resizing rewrites the vertices.
* ``cylinder``: the body's one mesh geom, unrotated, a regular prism of ``CYLINDER_SIDES`` sides
  whose vertices lie on the cylinder (``cylinder_vertices``): MJX collides no cylinder with a
  box, but both engines collide a convex mesh with one. Like a box, a resized cylinder keeps the
  end nearest its body's origin where it was.
* ``box_with_hole``: five box geoms (four walls, a bottom) in the body frame, origin at the bottom
  centre; all five are rewritten from the outer size, the hole's depth and its clearance.
* ``box_with_round_hole``: the same box with a round hole, drawn by ``ROUND_HOLE_GEOMS`` box
  geoms in file order (``box_with_round_hole_parts``): four walls around a square opening, the
  ``CYLINDER_SIDES`` slabs whose inner faces are tangent to the hole's circle (a regular
  polygon around it, its flats facing the held cylinder's vertices), and the bottom.
* ``pose``: nothing to draw, no inertia.

The inertia is the uniform solid's tensor about its centroid (the cylinder's and the round hole's
as round, not as the polygons that draw them); an uneven weight distribution (``com_offset``)
moves the centre of mass and keeps that tensor, as the hand-written push scene did (the
distribution itself is unknown).

A hole's size is relative to the item the robot holds (``HeldItem``): a square hole is
``hole_clearance`` wider on each side than a held box (or cylinder), a round hole's radius
``hole_clearance`` larger than a held cylinder's. With the cylinder's vertices on its circle and
the hole's flats on its own, the drawn gap is nowhere smaller than the clearance (and at most
``hole radius / cos(pi / sides) - radius`` where a vertex faces a corner: 1.8 mm for 1.5 mm).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import mujoco
import numpy as np

from mjxskill.errors import quote


class ShapeError(ValueError):
    """What the MJCF does not let a shape be drawn as the YAML says: (YAML key, message)."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key


# A cylinder's polygon: 16 sides keep the drawn gap within 0.3 mm of a 1.5 mm clearance at the
# peg's 15 mm radius, and every side is one more box of the round hole (one more contact pair).
CYLINDER_SIDES = 16
ROUND_HOLE_GEOMS = 4 + CYLINDER_SIDES + 1  # outer walls, slabs, bottom


class HeldItem(NamedTuple):
    """The item the robot holds, to which a hole's clearance is relative: its name, shape and
    size (the world model's)."""

    name: str
    shape: str
    size: np.ndarray


class Drawn(NamedTuple):
    """The MJCF side of one object: its body (``mujoco.MjsBody``), that body's geoms in file order
    and their compiled poses in the body frame (pos (G, 3), rotation (G, 3, 3)). hole_item: the
    ``HeldItem`` (a hole's clearance is relative to it), or None."""

    body: mujoco.MjsBody
    geoms: list
    geom_pos: np.ndarray
    geom_rot: np.ndarray
    hole_item: HeldItem | None


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
                                  f"of body {quote(drawn.body.name)}; it has {found}")
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
        raise ShapeError("shape", f"the prism's mesh geom {quote(geom.name)} must sit at its body's origin, unrotated "
                                  f"(the body origin is the prism's centroid)")
    return i


def _prism_inertia(size, extra, drawn: Drawn):
    _prism_geom(drawn)
    return np.zeros(3), prism_tensor(size)


def _prism_draw(size, extra, drawn: Drawn, spec):
    geom = drawn.geoms[_prism_geom(drawn)]
    mesh = spec.mesh(geom.meshname)
    if len(mesh.uservert) != 18:
        raise ShapeError("shape", f"the prism's mesh {quote(geom.meshname)} has {len(mesh.uservert) // 3} vertices, not 6")
    mesh.uservert = prism_vertices(size).ravel().tolist()


# -- cylinder -----------------------------------------------------------------------------------
def cylinder_tensor(size) -> np.ndarray:
    """(3, 3) inertia per kg of a uniform solid cylinder, ``size`` = (radius, height), axis z,
    about its centre."""
    r, h = (float(v) for v in size)
    side = (3 * r * r + h * h) / 12.0
    return np.diag([side, side, r * r / 2.0])


def cylinder_vertices(size, sides: int = CYLINDER_SIDES) -> np.ndarray:
    """(2 sides, 3) vertices of the regular prism drawing the cylinder (radius, height), centred
    at the origin: the bottom polygon, then the top; vertex k at angle 2 pi k / sides from +x, on
    the circle (the prism lies inside the cylinder)."""
    r, h = (float(v) for v in size)
    angle = 2 * np.pi * np.arange(sides) / sides
    ring = np.stack([r * np.cos(angle), r * np.sin(angle)], axis=1)
    return np.array([[x, y, z] for z in (-h / 2, h / 2) for x, y in ring])


def _cylinder_geom(drawn: Drawn, spec) -> int:
    i = _one_geom(drawn, "cylinder", mujoco.mjtGeom.mjGEOM_MESH)
    geom = drawn.geoms[i]
    if not np.allclose(drawn.geom_rot[i], np.eye(3)) or np.any(np.array(geom.quat) != [1, 0, 0, 0]):
        raise ShapeError("shape", f"the cylinder's mesh geom {quote(geom.name)} must be unrotated (its axis is the body's z)")
    vertices = np.reshape(spec.mesh(geom.meshname).uservert, (-1, 3))
    if len(vertices) != 2 * CYLINDER_SIDES or np.abs(vertices.max(axis=0) + vertices.min(axis=0)).max() > 1e-9:
        raise ShapeError("shape", f"the cylinder's mesh {quote(geom.meshname)} must be a prism of {2 * CYLINDER_SIDES} "
                                  f"vertices centred on its geom's origin (cylinder_vertices); it has {len(vertices)}")
    return i


def mesh_half_extent(geom, spec) -> np.ndarray:
    """(3,) half extents of a mesh geom's vertices as written (a centred mesh: about its origin)."""
    vertices = np.reshape(spec.mesh(geom.meshname).uservert, (-1, 3))
    return (vertices.max(axis=0) - vertices.min(axis=0)) / 2


def _cylinder_inertia(size, extra, drawn: Drawn):
    i = _one_geom(drawn, "cylinder", mujoco.mjtGeom.mjGEOM_MESH)
    return drawn.geom_pos[i].copy(), cylinder_tensor(size)


def _cylinder_draw(size, extra, drawn: Drawn, spec):
    geom = drawn.geoms[_cylinder_geom(drawn, spec)]
    old = mesh_half_extent(geom, spec)[2]
    spec.mesh(geom.meshname).uservert = cylinder_vertices(size).ravel().tolist()
    # the extent as stored (float32, as the old one), so an unchanged height moves nothing
    new = mesh_half_extent(geom, spec)[2]
    pos = np.array(geom.pos, float)
    # keep the end nearest the body origin: a mounted tool stays on its flange
    pos[2] += np.sign(pos[2]) * (new - old)
    geom.pos = pos


# -- boxes with a hole --------------------------------------------------------------------------
def _held(hole_item: HeldItem | None, shapes: tuple[str, ...], hole: str) -> HeldItem:
    if hole_item is None or hole_item.shape not in shapes:
        what = "there is none" if hole_item is None else f"{hole_item.name} is a {hole_item.shape}"
        raise ShapeError("extra.hole_clearance", f"{hole}'s clearance is relative to the item the robot holds (a "
                                                 f"(holding ...) relation to an object of shape {' or '.join(shapes)}): "
                                                 f"{what}")
    return hole_item


def hole_half_widths(extra, hole_item: HeldItem | None) -> np.ndarray:
    """(2,) m: a square hole's half-widths, those of the held box (x-y size; a held cylinder's
    diameter) plus the clearance."""
    held = _held(hole_item, ("box", "cylinder"), "a square hole")
    footprint = held.size[:2] if held.shape == "box" else np.full(2, 2 * held.size[0])
    return np.asarray(footprint, float) / 2 + float(extra["hole_clearance"])


def hole_radius(extra, hole_item: HeldItem | None) -> float:
    """m: a round hole's radius, the held cylinder's plus the clearance."""
    return float(_held(hole_item, ("cylinder",), "a round hole").size[0]) + float(extra["hole_clearance"])


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
        raise ShapeError("shape", f"a box_with_hole is drawn by five unrotated box geoms of body {quote(drawn.body.name)} "
                                  f"(four walls and a bottom); it has {len(drawn.geoms)} geoms")
    pos = drawn.geom_pos
    bottom = min(boxes, key=lambda i: pos[i, 2])
    walls = [i for i in boxes if i != bottom]
    order = [max(walls, key=lambda i: pos[i, 0]), min(walls, key=lambda i: pos[i, 0]),
             max(walls, key=lambda i: pos[i, 1]), min(walls, key=lambda i: pos[i, 1])]
    if len(set(order)) != 4:
        raise ShapeError("shape", f"the walls of body {quote(drawn.body.name)} are not one on each side of the hole")
    for i, (centre, half) in zip(order + [bottom], box_with_hole_parts(size, extra, drawn)):
        drawn.geoms[i].pos = centre
        drawn.geoms[i].size = half


# -- box with a round hole ----------------------------------------------------------------------
def box_with_round_hole_parts(size, extra, drawn: Drawn) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """(centre (3,), half size (3,), yaw rad) of the ``ROUND_HOLE_GEOMS`` boxes, body frame: the
    walls +x, -x, +y, -y around a square opening of half-width h = min(x, y) / (2 sqrt 2); the
    slabs k = 0 .. sides - 1 facing angle 2 pi k / sides, inner face tangent to the hole's circle
    (radius R), outer face at h sqrt 2 (the opening's corners), wide enough that neighbours meet
    there, so that together they fill the opening outside the polygon; the bottom."""
    ax, ay, c = np.asarray(size, float) / [2, 2, 1]
    radius = hole_radius(extra, drawn.hole_item)
    depth = float(extra["hole_depth"])
    h = min(ax, ay) / np.sqrt(2)
    if not (radius < h and depth < c):
        raise ShapeError("size", f"the round hole ({2 * radius:.4g} m across, {depth:g} m deep) does not fit in the box "
                                 f"({2 * ax:g} x {2 * ay:g} x {c:g} m: it must be narrower than the box's smaller "
                                 f"side / sqrt 2 and shallower than the box)")
    zc, dz = c - depth / 2, depth / 2
    walls = [(np.array([s * (ax + h) / 2, 0, zc]), np.array([(ax - h) / 2, ay, dz]), 0.0) for s in (1, -1)]
    walls += [(np.array([0, s * (ay + h) / 2, zc]), np.array([h, (ay - h) / 2, dz]), 0.0) for s in (1, -1)]
    outer = h * np.sqrt(2)
    thick, half_wide = (outer - radius) / 2, outer * np.tan(np.pi / CYLINDER_SIDES)
    slabs = []
    for k in range(CYLINDER_SIDES):
        yaw = 2 * np.pi * k / CYLINDER_SIDES
        mid = radius + thick
        slabs.append((np.array([mid * np.cos(yaw), mid * np.sin(yaw), zc]), np.array([thick, half_wide, dz]), yaw))
    bottom = (np.array([0, 0, (c - depth) / 2]), np.array([ax, ay, (c - depth) / 2]), 0.0)
    return walls + slabs + [bottom]


def _box_with_round_hole_inertia(size, extra, drawn: Drawn):
    # the solid box less the round hole (not the overlapping boxes that draw it)
    a, b, c = (float(v) for v in size)
    radius, depth = hole_radius(extra, drawn.hole_item), float(extra["hole_depth"])
    solids = [(a * b * c, np.array([0, 0, c / 2]), box_tensor(size)),
              (-np.pi * radius ** 2 * depth, np.array([0, 0, c - depth / 2]), cylinder_tensor((radius, depth)))]
    volume = sum(v for v, _, _ in solids)
    centroid = sum(v * p for v, p, _ in solids) / volume
    tensor = np.zeros((3, 3))
    for v, p, own in solids:
        d = p - centroid
        tensor += v / volume * (own + np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return centroid, tensor


def _box_with_round_hole_draw(size, extra, drawn: Drawn, spec):
    if len(drawn.geoms) != ROUND_HOLE_GEOMS or any(g.type != mujoco.mjtGeom.mjGEOM_BOX for g in drawn.geoms):
        raise ShapeError("shape", f"a box_with_round_hole is drawn by {ROUND_HOLE_GEOMS} box geoms of body "
                                  f"{quote(drawn.body.name)} (four walls, {CYLINDER_SIDES} slabs around the hole, a bottom, "
                                  f"in that order); it has {len(drawn.geoms)} geoms")
    for geom, (centre, half, yaw) in zip(drawn.geoms, box_with_round_hole_parts(size, extra, drawn)):
        geom.pos = centre
        geom.size = half
        geom.quat = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
        geom.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT


SHAPE_MODELS: dict[str, ShapeModel] = {
    "pose": ShapeModel(None, None),
    "box": ShapeModel(_box_inertia, _box_draw),
    "right_triangle_prism": ShapeModel(_prism_inertia, _prism_draw),
    "cylinder": ShapeModel(_cylinder_inertia, _cylinder_draw),
    "box_with_hole": ShapeModel(_box_with_hole_inertia, _box_with_hole_draw),
    "box_with_round_hole": ShapeModel(_box_with_round_hole_inertia, _box_with_round_hole_draw),
}


__all__ = ["CYLINDER_SIDES", "ROUND_HOLE_GEOMS", "SHAPE_MODELS", "Drawn", "HeldItem", "ShapeError", "box_tensor",
           "box_with_hole_parts", "box_with_round_hole_parts", "cylinder_tensor", "cylinder_vertices",
           "hole_half_widths", "hole_radius", "mesh_half_extent", "prism_tensor", "prism_vertices"]
