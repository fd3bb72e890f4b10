"""The scenario's references into its MJCF scene, checked when the scenario loads.

A scene path that is missing, a directory or not MJCF, a ``robot.tool_site`` that is not a site
of the scene, an ``objects.<name>.mjcf_body`` that is not one of its bodies or an
``objects.<name>.mjcf_geom`` that is not a geom of its world body is a
``ScenarioError`` naming the key and its line, raised before anything runs or is written. The
engines would otherwise find out late (a traceback after a run directory exists) or never (a
misspelled body silently became a fixed pose, and a whole budget trained at 0 % success).

The scene is compiled with native MuJoCo (about 15 ms for push): no JAX, so ``mjxskill.plan``
stays cheap.
"""

from __future__ import annotations

from pathlib import Path

import mujoco

from mjxskill.errors import listing, quote
from mjxskill.planner.world_pddl import close_matches
from mjxskill.scenario.fields import Field


def check_scene(scene: Path, scene_field: Field, tool_site: Field, bodies: dict[str, Field],
                geoms: dict[str, Field] | None = None) -> None:
    """Raises ScenarioError unless ``scene`` is an MJCF file with the site ``tool_site`` names,
    every body ``bodies`` (key path -> an ``mjcf_body`` field) names and every geom of the world
    body ``geoms`` (key path -> an ``mjcf_geom`` field) names."""
    try:
        exists = scene.exists()
    except OSError as err:  # a name too long, a loop of links
        scene_field.fail(f"the MJCF scene {quote(str(scene), 300)} cannot be read ({err.strerror})")
    if not exists:
        scene_field.fail(f"the MJCF scene {quote(str(scene), 300)} does not exist (paths are relative to the scenario file)")
    if not scene.is_file():
        scene_field.fail(f"the MJCF scene {quote(str(scene), 300)} is {'a directory' if scene.is_dir() else 'not a regular file'}, not an MJCF file")
    try:
        model = mujoco.MjModel.from_xml_path(str(scene))
    except Exception as err:  # noqa: BLE001  (MuJoCo reports every XML and model problem as one exception)
        problem = " ".join(str(err).split())
        scene_field.fail(f"{quote(str(scene), 300)} is not a MuJoCo MJCF scene: {problem[:300]}")
    site_name = tool_site.string()
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site_name) < 0:
        sites = _names(mujoco, model, mujoco.mjtObj.mjOBJ_SITE, model.nsite)
        tool_site.fail(f"the scene {scene.name} has no site {quote(site_name)}{close_matches(site_name, sites)} "
                       f"(sites: {listing(sites) or 'none'})")
    known = None
    for field in bodies.values():
        if field.is_null():
            continue
        name = field.string()
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) < 0:
            known = known or _names(mujoco, model, mujoco.mjtObj.mjOBJ_BODY, model.nbody)
            field.fail(f"the scene {scene.name} has no body {quote(name)}{close_matches(name, known)} "
                       f"(bodies: {listing(known)}; null for an object without a body)")
    for field in (geoms or {}).values():
        if field.is_null():
            continue
        name = field.string()
        geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
        if geom < 0 or model.geom_bodyid[geom] != 0:
            world = [n for n in _names(mujoco, model, mujoco.mjtObj.mjOBJ_GEOM, model.ngeom)
                     if model.geom_bodyid[model.geom(n).id] == 0]
            field.fail(f"the scene {scene.name} has no geom {quote(name)} in its world body{close_matches(name, world)} "
                       f"(world geoms: {listing(world) or 'none'})")


def _names(mujoco, model, kind, count: int) -> list[str]:
    return [n for n in (mujoco.mj_id2name(model, kind, i) for i in range(count)) if n]


__all__ = ["check_scene"]
