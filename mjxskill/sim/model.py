"""The simulated model of a scenario: its MJCF scene with the world model's physics written in
(``mujoco.MjSpec``, MuJoCo's model editing API). Both engines, rendering and evaluation
simulate this model; ``mjxskill.load_scenario`` builds it to refuse, naming the YAML entry, what
the simulator cannot honour, and that build is the one every later ``build_model`` of the same
scenario copies (a process compiles a scenario's model once).

What the YAML sets (``build_model``), per object of the world model:

* ``mass`` and ``com_offset``: the body's mass, centre of mass (the shape's centroid plus the
  offset) and inertia (the uniform shape's, ``mjxskill.sim.shapes``). A mocap body or a body
  fixed to the world does not move: mass on it is an error.
* ``friction``: the sliding friction of the body's geoms (or of its ``mjcf_geom``), and of every
  contact pair touching them: a pair takes the larger of the frictions the YAML gives its two
  sides (MuJoCo's rule for two geoms in contact); a pair with neither side in the YAML keeps the
  MJCF's. Per-world friction randomization then overrides the pairs of the randomized object.
* ``size`` (and a shape's ``extra``): the geoms that draw the shape (``mjxskill.sim.shapes``);
  the robot's tool site moves with the face of a held tool it sits on. A plane geom
  (``mjcf_geom``) takes the x-y size as its drawn half-extents (a plane's contact is infinite).
* ``pose``: bodies of the world body (free, mocap or fixed) start there; an object on the robot
  moves with it (its pose is not used), and a body nested in another must already be there.

Plus the scenario's gravity and control period (one physics step per control step), and a touch
sensor around every body the tool consists of (``mjxskill.sim.tool_force``): the measured
contact force of both engines; and ``CONTROL_USERDATA`` numbers of ``userdata`` for the native
engine's control callback.
"""

from __future__ import annotations

import copy
import re
import weakref
from typing import NoReturn

import mujoco
import numpy as np

from mjxskill.errors import ScenarioError, quote
from mjxskill.sim.shapes import SHAPE_MODELS, Drawn, HeldItem, ShapeError, mesh_half_extent
from mjxskill.sim.tool_force import add_tool_force_sensors


# numbers of ``userdata`` the model ends with for the native engine's control callback: a row
# finds its batch's context and its index there (mjxskill.engine.native.callback); they change
# no physics, and MJX carries them unread
CONTROL_USERDATA = 2

# scenario -> its model, built on the first request (load_scenario's); dropped with the scenario
_BUILT: "weakref.WeakKeyDictionary[object, mujoco.MjModel]" = weakref.WeakKeyDictionary()


def build_model(scn) -> mujoco.MjModel:
    """The MjModel of scenario ``scn`` (a ``mjxskill.scenario.Scenario``): its MJCF with the
    YAML's physics, gravity and control period applied (see the module docstring). Raises
    ScenarioError naming the YAML entry the simulator cannot honour. Built once per scenario
    object; every call returns a copy of its own (``mj_copyModel``), free to modify."""
    model = _BUILT.get(scn)
    if model is None:
        model = _BUILT[scn] = compile_model(scn)
    return copy.copy(model)


def compile_model(scn) -> mujoco.MjModel:
    """``build_model``'s work, done every time: three MjSpec compiles (the MJCF as written, with
    the tool's force sensors placed, and the final model)."""
    return _compile(scenario_spec(scn), scn)


def scenario_spec(scn) -> mujoco.MjSpec:
    """The ``mujoco.MjSpec`` that compiles to ``build_model(scn)``: the MJCF with the YAML's
    physics written in (two compiles: the MJCF as written, and with the tool's force sensors
    placed). What edits the twin further starts here (``mjxskill.calibration``: the twin whose
    object physics is fitted). Raises ScenarioError as ``build_model``."""
    spec = mujoco.MjSpec.from_file(scn.scene)
    base = _compile(spec, scn)  # the MJCF as written: poses, masses, where the tool tip is
    data = mujoco.MjData(base)
    mujoco.mj_kinematics(base, data)
    site = base.site(scn.robot.tool_site).id
    robot = _subtree(base, _root_child(base, int(base.site_bodyid[site])))
    hole_item = held_item(scn)
    for obj in scn.objects.values():
        if obj.mjcf_body is not None:
            _body_physics(spec, base, data, scn, obj, robot, hole_item, site)
        elif obj.mjcf_geom is not None:
            _world_geom(spec, scn, obj)
    write_friction(spec, scn)
    spec.option.timestep = 1.0 / scn.control_hz
    if not scn.gravity:
        spec.option.gravity = [0.0, 0.0, 0.0]
    add_tool_force_sensors(spec, _compile(spec, scn), scn.robot.tool_site)
    spec.nuserdata += CONTROL_USERDATA
    return spec


def _compile(spec, scn) -> mujoco.MjModel:
    """``spec.compile()``, MuJoCo's refusal (a degenerate mesh, an inertia that is not positive
    definite) a ScenarioError naming the YAML entry of the object it is about."""
    try:
        return spec.compile()
    except ValueError as err:
        raise ScenarioError(_compile_error(spec, scn, str(err))) from None


def _compile_error(spec, scn, text: str) -> str:
    """The message of MuJoCo's compile error ``text``: at the YAML entry of the object whose body,
    geom or mesh MuJoCo names (its size; its mass where the inertia is at fault and the YAML
    gives one), else at the scenario's objects."""
    problem = " ".join(text.split("Element name")[0].removeprefix("Error:").split())[:300]
    match = re.search(r"Element name '([^']*)'", text)
    element = match.group(1) if match else None
    for obj in scn.objects.values():
        if element and element in _element_names(spec, obj):
            inertia = "inertia" in problem or "mass" in problem
            key = "mass" if inertia and obj.mass is not None else "size"
            return (f"{scn.where(f'objects.{obj.name}.{key}')}: MuJoCo cannot build the simulated model with this value: "
                    f"{problem}")
    return f"{scn.source}: objects: MuJoCo cannot build the simulated model from the objects' values: {problem}"


def _element_names(spec, obj) -> set[str]:
    """The names of the MJCF elements that simulate ``obj``: its body, geoms and their meshes."""
    if obj.mjcf_body is not None:
        body = spec.body(obj.mjcf_body)
        geoms = list(body.geoms) if body is not None else []
        names = {obj.mjcf_body}
    elif obj.mjcf_geom is not None:
        geom = spec.geom(obj.mjcf_geom)
        geoms = [geom] if geom is not None else []
        names = {obj.mjcf_geom}
    else:
        return set()
    for geom in geoms:
        names |= {geom.name, geom.meshname} - {""}
    return names


def _fail(scn, obj, key: str, message: str) -> NoReturn:
    raise ScenarioError(f"{scn.where(f'objects.{obj.name}.{key}')}: {message}")


def _root_child(model: mujoco.MjModel, body: int) -> int:
    """The ancestor of ``body`` that is a child of the world body."""
    while model.body_parentid[body] != 0:
        body = int(model.body_parentid[body])
    return body


def _subtree(model: mujoco.MjModel, root: int) -> set[int]:
    return {b for b in range(model.nbody) if b == root or _ancestors(model, b) & {root}}


def _ancestors(model: mujoco.MjModel, body: int) -> set[int]:
    out = set()
    while body != 0:
        body = int(model.body_parentid[body])
        out.add(body)
    return out


def held_item(scn) -> HeldItem | None:
    """The item the robot holds, when it holds exactly one object with a shape (a hole's
    clearance is relative to it)."""
    robot = scn.robot.pddl_name
    facts = {*scn.robot.relations, *(r for o in scn.objects.values() for r in o.relations)}
    held = [o for o in scn.objects.values() if f"(holding {robot} {o.pddl_name})" in facts and o.shape != "pose"]
    return HeldItem(held[0].name, held[0].shape, np.asarray(held[0].size, float)) if len(held) == 1 else None


def _geom_poses(model: mujoco.MjModel, body: int):
    ids = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body]
    rot = np.zeros((len(ids), 9))
    for k, g in enumerate(ids):
        mujoco.mju_quat2Mat(rot[k], model.geom_quat[g])
    return ids, model.geom_pos[ids].copy(), rot.reshape(-1, 3, 3)


def _body_physics(spec, base, data, scn, obj, robot: set[int], hole_item, site: int) -> None:
    body_id = base.body(obj.mjcf_body).id
    body = spec.body(obj.mjcf_body)
    ids, pos, rot = _geom_poses(base, body_id)
    drawn = Drawn(body, list(body.geoms), pos, rot, hole_item)
    shape = SHAPE_MODELS[obj.shape]
    on_robot = body_id in robot
    moves = on_robot or base.body_jntnum[body_id] > 0
    if (obj.mass is not None or np.any(obj.com_offset)) and not moves:
        what = "a mocap body" if base.body_mocapid[body_id] >= 0 else "fixed to the world"
        key = "mass" if obj.mass is not None else "com_offset"
        _fail(scn, obj, key, f"body {quote(obj.mjcf_body)} is {what}: it does not move, so the simulator has no use for "
                             f"its {key}; drop it (or give the body a joint in the MJCF)")
    try:
        if obj.mass is not None or np.any(obj.com_offset):
            if shape.inertia is None:
                _fail(scn, obj, "mass", f"a {obj.shape} has no inertia; give the object a shape")
            centroid, tensor = shape.inertia(obj.size, obj.extra, drawn)
            mass = float(base.body_mass[body_id]) if obj.mass is None else obj.mass
            body.explicitinertial = True
            body.mass = mass
            body.ipos = centroid + np.asarray(obj.com_offset, float)
            t = mass * tensor
            body.fullinertia = [t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]]
        if shape.draw is not None:
            faces = _faces(drawn, spec) if on_robot else None
            shape.draw(obj.size, obj.extra, drawn, spec)
            if faces is not None:
                _follow_tool_tip(spec, base, data, scn, body_id, drawn, faces, site)
    except ShapeError as err:
        _fail(scn, obj, err.key, str(err))
    if not on_robot:
        _place(spec, base, data, scn, obj, body_id, body)


def _faces(drawn: Drawn, spec) -> list[np.ndarray] | None:
    """Centres (6, 3) of the faces of the body's single box geom (or of the box around its single
    mesh geom, which is centred on its origin: a cylinder's ends) in the body frame, or None."""
    if len(drawn.geoms) != 1 or drawn.geoms[0].type not in (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_MESH):
        return None
    geom = drawn.geoms[0]
    half = np.array(geom.size[:3], float) if geom.type == mujoco.mjtGeom.mjGEOM_BOX else mesh_half_extent(geom, spec)
    centre = np.array(geom.pos, float)
    return [centre + s * drawn.geom_rot[0][:, j] * half[j] for j in range(3) for s in (1, -1)]


def _follow_tool_tip(spec, base, data, scn, body_id: int, drawn: Drawn, old_faces, site: int) -> None:
    """The robot's tool site sat on a face of this held tool: it moves with that face."""
    body_rot = data.xmat[body_id].reshape(3, 3)
    tip = body_rot.T @ (data.site_xpos[site] - data.xpos[body_id])  # the site in this body's frame
    new_faces = _faces(drawn, spec)
    assert new_faces is not None  # the geom the caller found faces of before drawing, resized only
    for old, new in zip(old_faces, new_faces):
        if np.linalg.norm(tip - old) < 1e-6:
            site_body = int(base.site_bodyid[site])
            shift = data.xmat[site_body].reshape(3, 3).T @ (body_rot @ (new - old))
            tool_site = spec.site(scn.robot.tool_site)
            tool_site.pos = np.array(tool_site.pos, float) + shift
            return


def _place(spec, base, data, scn, obj, body_id: int, body) -> None:
    """The YAML pose for a body of the world body; a nested body must already be there."""
    if base.body_parentid[body_id] == 0:
        body.pos = np.asarray(obj.pose.position, float)
        body.quat = np.asarray(obj.pose.quat, float)
        body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
        return
    offset = np.linalg.norm(data.xpos[body_id] - obj.pose.position)
    turn = 2 * np.degrees(np.arccos(min(1.0, abs(float(np.dot(data.xquat[body_id], obj.pose.quat))))))
    if offset > 1e-3 or turn > 0.1:
        _fail(scn, obj, "pose", f"body {quote(obj.mjcf_body)} is nested in another body, so the simulator cannot move "
                                f"it; the MJCF puts it {offset * 1000:.1f} mm and {turn:.1f} deg away from this pose")


def _world_geom(spec, scn, obj) -> None:
    """An object that is a geom of the world body (the table): its drawn size."""
    geom = spec.geom(obj.mjcf_geom)
    if obj.shape == "pose":
        return
    if obj.shape != "box":
        _fail(scn, obj, "shape", f"a geom of the world body is drawn as a box or a plane, not a {obj.shape}")
    if geom.type == mujoco.mjtGeom.mjGEOM_PLANE:
        if obj.size[2] != 0:
            _fail(scn, obj, "size", f"geom {quote(obj.mjcf_geom)} is a plane: its height must be 0, got {obj.size[2]:g}")
        geom.size = [obj.size[0] / 2, obj.size[1] / 2, geom.size[2]]
    elif geom.type == mujoco.mjtGeom.mjGEOM_BOX:
        if obj.size[2] == 0:
            _fail(scn, obj, "size", f"geom {quote(obj.mjcf_geom)} is a box: its height must be > 0 (only a plane's is 0)")
        geom.size = np.asarray(obj.size, float) / 2
    else:
        _fail(scn, obj, "shape", f"geom {quote(obj.mjcf_geom)} is a {geom.type.name.removeprefix('mjGEOM_').lower()}, "
                                 f"not a box or a plane")
    geom.pos = np.asarray(obj.pose.position, float)
    geom.quat = np.asarray(obj.pose.quat, float)


def write_friction(spec, scn, changed: dict[str, float] | None = None) -> None:
    """Objects' friction on their geoms and on the contact pairs touching them (a pair takes the
    larger of its two sides, see the module docstring), with the frictions ``changed`` gives
    (object name -> coefficient) in place of the YAML's: what fitting an object's friction
    writes into a spec (``mjxskill.calibration``)."""
    changed = changed or {}
    of_geom: dict[str, float] = {}
    for obj in scn.objects.values():
        friction = changed.get(obj.name, obj.friction)
        if friction is None:
            continue
        geoms = list(spec.body(obj.mjcf_body).geoms) if obj.mjcf_body is not None else [spec.geom(obj.mjcf_geom)]
        for geom in geoms:
            geom.friction = [friction, *list(geom.friction)[1:]]
            if geom.name:
                of_geom[geom.name] = friction
    for pair in spec.pairs:
        sides = [of_geom[g] for g in (pair.geomname1, pair.geomname2) if g in of_geom]
        if sides:
            friction = list(pair.friction)
            friction[0] = friction[1] = max(sides)
            pair.friction = friction


__all__ = ["build_model", "held_item", "scenario_spec", "write_friction"]
