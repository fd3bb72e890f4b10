"""The measured interaction force: the normal contact force between the tool (or the item it
holds) and everything else, read from MuJoCo's own contact forces on both engines.

``add_tool_force_sensors`` puts a MuJoCo ``touch`` sensor on every body the tool consists of
(the tool site's body and the bodies below it, e.g. the flange and the attached tool) that has a
colliding geom. A touch sensor sums the normal forces (``mj_contactForce``) of the contacts of
its body whose point lies in its site's volume; the site here is a box around all of the body's
geoms plus a margin, so every contact of the body counts. MuJoCo computes it in C at each
``mj_step`` and MJX inside ``mjx.step``: a reading per step costs the engines one array read
(``tool_force_addresses`` gives where in ``sensordata``). The sum of the readings is the force
the tool exerts on the world, N (the arm's links never collide: only the tool and the objects
have contact pairs).
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np

PREFIX = "mjxskill_touch_"  # site and sensor names: PREFIX + body name
MARGIN = 0.02  # m around the body's geoms: contact points lie on their surfaces


def _tool_bodies(model: mujoco.MjModel, site: str) -> list[int]:
    root = int(model.site_bodyid[model.site(site).id])
    bodies = []
    for b in range(model.nbody):
        a = b
        while a not in (root, 0):
            a = int(model.body_parentid[a])
        if a == root:
            bodies.append(b)
    return bodies


def _colliding(model: mujoco.MjModel, geom: int) -> bool:
    in_pair = np.any(model.pair_geom1 == geom) or np.any(model.pair_geom2 == geom)
    return bool(in_pair or model.geom_contype[geom] or model.geom_conaffinity[geom])


def _box_around(model: mujoco.MjModel, geoms: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Centre (3,) and half size (3,) in the body frame of a box holding ``geoms``' bounding boxes."""
    corners = []
    for g in geoms:
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[g])
        for signs in itertools.product((-1, 1), repeat=3):
            corners.append(model.geom_pos[g] + rot.reshape(3, 3) @ (centre + np.array(signs) * half))
    points = np.array(corners)
    low, high = points.min(axis=0) - MARGIN, points.max(axis=0) + MARGIN
    return (low + high) / 2, (high - low) / 2


def add_tool_force_sensors(spec: mujoco.MjSpec, model: mujoco.MjModel, site: str) -> None:
    """Adds a touch site and sensor to ``spec`` for every colliding body of the tool below the
    site ``site`` (``model``: ``spec`` compiled, for the geoms' extents)."""
    for body in _tool_bodies(model, site):
        geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body and _colliding(model, g)
                 and model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE]
        if not geoms:
            continue
        name = PREFIX + model.body(body).name
        centre, half = _box_around(model, geoms)
        spec.body(model.body(body).name).add_site(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=centre, size=half,
                                                  group=5, rgba=[0, 0, 0, 0])
        spec.add_sensor(name=name, type=mujoco.mjtSensor.mjSENS_TOUCH, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=name)


def tool_force_addresses(model: mujoco.MjModel) -> tuple[int, ...]:
    """Addresses in ``sensordata`` of the tool's touch sensors (their sum is the measured force)."""
    return tuple(int(model.sensor_adr[s]) for s in range(model.nsensor)
                 if model.sensor_type[s] == mujoco.mjtSensor.mjSENS_TOUCH
                 and (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, s) or "").startswith(PREFIX))


__all__ = ["PREFIX", "add_tool_force_sensors", "tool_force_addresses"]
