"""build_model: the simulated model is the MJCF scene with the world model's physics written
in. References: the hand-written MJCF (the shipped YAMLs must not change the
physics), MuJoCo's own inertia of uniform geoms, closed forms, and rollouts of edited copies on
the native engine (no compile)."""

from __future__ import annotations

import jax
import mujoco
import numpy as np
import pytest

from mjxskill import build_model, load_scenario
from mjxskill.errors import ScenarioError
from mjxskill.engine.native import NativeRollout
from mjxskill.sim.shapes import (
    CYLINDER_SIDES, SHAPE_MODELS, Drawn, HeldItem, ShapeError, box_tensor, box_with_hole_parts, box_with_round_hole_parts,
    cylinder_tensor, cylinder_vertices, prism_tensor, prism_vertices,
)
from mjxskill.scenario.vocabulary import SHAPES
from mjxskill.task import plan_task
from scenario_texts import shipped_text, write_copy

HAND_FOUND = np.array([-0.05, -0.15, 0.07, -0.10])  # the push into the goal corner (tests/engine/mjx/test_rollout_push.py)


def edited(tmp_path, name: str, *replacements) -> object:
    text = shipped_text(name)
    for old, new in replacements:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    tmp_path.mkdir(parents=True, exist_ok=True)
    return load_scenario(write_copy(tmp_path, name, text))


@pytest.mark.parametrize("name", ["push", "peg", "peg_square", "slide"])
def test_the_shipped_yaml_and_mjcf_agree(name):
    # Building the shipped scenarios changes nothing the MJCF already said: same masses, centres
    # of mass, geometry and pair frictions. The prism's inertia is the closed form; the MJCF held
    # it rounded to 4 digits. (Measured against the hand-written model's code on main: a short
    # push run gives the same success rates and forces, its objectives differ by < 1e-10
    # relative; peg rollouts agree to 10 digits.)
    scn = load_scenario(name)
    built, raw = build_model(scn), mujoco.MjModel.from_xml_path(scn.scene)
    for field in ("body_mass", "body_ipos", "body_pos", "geom_size", "geom_pos", "geom_quat", "pair_friction", "mesh_vert"):
        np.testing.assert_allclose(getattr(built, field), getattr(raw, field), atol=2e-6, err_msg=field)
    # the inertia as a tensor in the body frame: a written inertia may list the same principal
    # moments in another order (body_iquat turned to match)
    np.testing.assert_allclose(_body_tensors(built), _body_tensors(raw), rtol=1e-4, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(built.body_quat * raw.body_quat, axis=1)), 1.0, atol=1e-9)
    np.testing.assert_array_equal(built.site_pos[built.site("tool").id], raw.site_pos[raw.site("tool").id])
    assert built.opt.timestep == 1.0 / scn.control_hz
    assert np.any(built.opt.gravity) == scn.gravity


def _body_tensors(model) -> np.ndarray:
    """(nbody, 3, 3) each body's inertia tensor about its centre of mass, in the body frame."""
    out = np.zeros((model.nbody, 3, 3))
    for b in range(model.nbody):
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.body_iquat[b])
        rot = rot.reshape(3, 3)
        out[b] = rot @ np.diag(model.body_inertia[b]) @ rot.T
    return out


def _principal(tensor):
    return np.sort(np.linalg.eigvalsh(tensor))


def _mujoco_inertia(geoms, mass: float):
    """Mass-scaled inertia (centroid (3,), tensor (3, 3)) MuJoCo infers for a body of uniform
    geoms: ``geoms`` adds them to the body of a fresh spec."""
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="b")
    body.add_freejoint()
    geoms(spec, body)
    model = spec.compile()
    b = model.body("b").id
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.body_iquat[b])
    rot = rot.reshape(3, 3)
    scale = mass / model.body_mass[b]
    return model.body_ipos[b], scale * rot @ np.diag(model.body_inertia[b]) @ rot.T


def test_the_prism_inertia_is_mujocos_and_the_hand_computed_one():
    size = (0.15, 0.30, 0.07)

    def prism(spec, body):
        spec.add_mesh(name="p", uservert=prism_vertices(size).ravel().tolist())
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="p")

    centroid, reference = _mujoco_inertia(prism, 2.5)
    np.testing.assert_allclose(centroid, 0.0, atol=1e-9)  # the vertices are centred on the centroid
    np.testing.assert_allclose(2.5 * prism_tensor(size), reference, rtol=1e-6)  # MuJoCo keeps mesh vertices in float32
    # the push scene's hand-written fullinertia (4 digits)
    hand = np.array([[0.01352, 0.003125, 0], [0.003125, 0.004146, 0], [0, 0, 0.015625]])
    np.testing.assert_allclose(2.5 * prism_tensor(size), hand, rtol=2e-4, atol=1e-9)


def test_the_box_and_the_box_with_hole_inertia_are_mujocos():
    size = (0.08, 0.05, 0.03)
    _, reference = _mujoco_inertia(lambda s, b: b.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=np.array(size) / 2), 0.7)
    np.testing.assert_allclose(0.7 * box_tensor(size), reference, rtol=1e-9)
    extra, outer = {"hole_clearance": 0.002, "hole_depth": 0.03}, (0.09, 0.07, 0.05)
    drawn = Drawn(None, [], np.zeros((0, 3)), np.zeros((0, 3, 3)), HeldItem("peg", "box", np.array([0.03, 0.02, 0.05])))
    parts = box_with_hole_parts(outer, extra, drawn)

    def walls(spec, body):
        for centre, half in parts:
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=centre, size=half)

    centroid, reference = _mujoco_inertia(walls, 1.3)
    ours_centroid, ours = SHAPE_MODELS["box_with_hole"].inertia(outer, extra, drawn)
    np.testing.assert_allclose(ours_centroid, centroid, atol=1e-12)
    np.testing.assert_allclose(1.3 * ours, reference, rtol=1e-9, atol=1e-12)


def test_the_cylinder_inertia_is_mujocos_and_its_prism_lies_on_it():
    size = (0.015, 0.05)
    _, reference = _mujoco_inertia(lambda s, b: b.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.015, 0.025, 0]), 0.2)
    np.testing.assert_allclose(0.2 * cylinder_tensor(size), reference, rtol=1e-9)
    vertices = cylinder_vertices(size)
    assert vertices.shape == (2 * CYLINDER_SIDES, 3)
    np.testing.assert_allclose(np.hypot(vertices[:, 0], vertices[:, 1]), 0.015)  # on the cylinder
    np.testing.assert_allclose(np.unique(vertices[:, 2]), [-0.025, 0.025])


def _round_hole(size, extra, radius):
    return Drawn(None, [], np.zeros((0, 3)), np.zeros((0, 3, 3)), HeldItem("peg", "cylinder", np.array([radius, 0.05])))


def _inside(parts, points):
    """(N,) bool: each point (N, 3) inside any of the boxes (centre, half, yaw)."""
    hit = np.zeros(len(points), bool)
    for centre, half, yaw in parts:
        c, s = np.cos(yaw), np.sin(yaw)
        local = (points - centre) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])  # rows: R^T p
        hit |= np.all(np.abs(local) <= half, axis=1)
    return hit


def test_the_round_hole_boxes_fill_the_box_but_a_hole_of_the_pegs_radius_plus_the_clearance():
    # Sampled against the solid it stands for: every point of the box outside the hole's circle
    # (beyond the polygon's 0.3 mm) is covered, none inside the circle, and nothing sticks out.
    outer, extra = (0.073, 0.073, 0.05), {"hole_clearance": 0.0015, "hole_depth": 0.04}
    parts = box_with_round_hole_parts(outer, extra, _round_hole(outer, extra, 0.015))
    points = np.random.default_rng(0).uniform([-0.04, -0.04, -0.005], [0.04, 0.04, 0.055], (200_000, 3))
    hit = _inside(parts, points)
    r = np.hypot(points[:, 0], points[:, 1])
    in_box = np.all(np.abs(points[:, :2]) <= 0.0365, axis=1) & (points[:, 2] >= 0) & (points[:, 2] <= 0.05)
    in_hole = (r < 0.0165) & (points[:, 2] > 0.01)
    polygon_gap = (r < 0.0165 / np.cos(np.pi / CYLINDER_SIDES)) & (points[:, 2] > 0.01)
    assert not hit[in_hole].any()
    assert hit[in_box & ~polygon_gap].all()
    assert not hit[~in_box].any()


def test_the_box_with_round_hole_inertia_is_the_solid_box_less_the_hole():
    # Monte Carlo over the solid (independent of the closed form): mass centre and tensor.
    outer, extra = (0.09, 0.07, 0.05), {"hole_clearance": 0.002, "hole_depth": 0.03}
    centroid, tensor = SHAPE_MODELS["box_with_round_hole"].inertia(outer, extra, _round_hole(outer, extra, 0.012))
    p = np.random.default_rng(1).uniform([-0.045, -0.035, 0.0], [0.045, 0.035, 0.05], (1_000_000, 3))
    p = p[~((np.hypot(p[:, 0], p[:, 1]) < 0.014) & (p[:, 2] > 0.02))]
    mean = p.mean(axis=0)
    d = p - mean
    sampled = np.eye(3) * np.mean(np.sum(d * d, axis=1)) - d.T @ d / len(d)
    np.testing.assert_allclose(centroid, mean, atol=5e-5)
    np.testing.assert_allclose(tensor, sampled, rtol=5e-3, atol=1e-6)  # sampling noise ~4e-7 on 1e-3


def test_a_round_hole_needs_a_held_cylinder():
    outer, extra = (0.073, 0.073, 0.05), {"hole_clearance": 0.0015, "hole_depth": 0.04}
    square_peg = Drawn(None, [], np.zeros((0, 3)), np.zeros((0, 3, 3)), HeldItem("Peg-1", "box", np.array([0.03, 0.03, 0.05])))
    with pytest.raises(ShapeError, match=r"shape cylinder\): Peg-1 is a box"):
        box_with_round_hole_parts(outer, extra, square_peg)


def test_every_shape_of_the_vocabulary_has_a_model():
    assert set(SHAPE_MODELS) == set(SHAPES)


def test_a_copy_with_other_mass_centre_of_mass_and_friction_gives_those_values(tmp_path):
    scn = edited(tmp_path, "push", ("    mass: 2.5", "    mass: 6.0"),
                 ("com_offset: [-0.02, 0.04, -0.005]", "com_offset: [0.01, -0.03, 0.0]"),
                 ("    friction: 0.2\n    pose: {position: [0.55", "    friction: 0.4\n    pose: {position: [0.55"))
    model = build_model(scn)
    prism = model.body("object").id
    assert model.body_mass[prism] == 6.0
    np.testing.assert_allclose(model.body_ipos[prism], [0.01, -0.03, 0.0], atol=1e-12)
    np.testing.assert_allclose(_principal(np.diag(model.body_inertia[prism])), _principal(6.0 * prism_tensor((0.15, 0.3, 0.07))),
                               rtol=1e-9)
    pairs = {frozenset((model.geom(int(model.pair_geom1[p])).name, model.geom(int(model.pair_geom2[p])).name)): model.pair_friction[p, :2]
             for p in range(model.npair)}
    # the larger of the two sides' frictions: 0.4 against the pusher's 0.25 and the table's 0.2
    for key in (("tool_geom", "object"), ("object", "table"), ("object", "fence")):
        np.testing.assert_array_equal(pairs[frozenset(key)], [0.4, 0.4])
    np.testing.assert_array_equal(pairs[frozenset(("tool_geom", "table"))], [0.25, 0.25])  # untouched by the prism


def test_a_tighter_hole_and_a_longer_peg_give_that_geometry(tmp_path):
    scn = edited(tmp_path, "peg_square", ("hole_clearance: 0.0015", "hole_clearance: 0.0004"),
                 ("size: [0.03, 0.03, 0.05]  # square peg", "size: [0.03, 0.03, 0.07]  # square peg"))
    model = build_model(scn)
    wall = model.geom("wall_px")
    assert wall.pos[0] - wall.size[0] == pytest.approx(0.015 + 0.0004)  # the hole's inner face
    peg = model.geom("tool_geom")
    np.testing.assert_allclose(peg.size, [0.015, 0.015, 0.035])
    np.testing.assert_allclose(peg.pos, [0, 0, 0.035])  # still mounted on the flange
    np.testing.assert_allclose(model.site("tool").pos, [0, 0, 0.07])  # the tool tip moved with the peg's end
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    bottom = data.geom_xpos[peg.id] + data.geom_xmat[peg.id].reshape(3, 3) @ [0, 0, 0.035]
    np.testing.assert_allclose(data.site_xpos[model.site("tool").id], bottom, atol=1e-12)


def test_a_tighter_round_hole_and_a_longer_thinner_round_peg_give_that_geometry(tmp_path):
    scn = edited(tmp_path, "peg", ("hole_clearance: 0.0015", "hole_clearance: 0.0004"),
                 ("size: [0.015, 0.05]  ", "size: [0.012, 0.07]  "))
    model = build_model(scn)
    for k in range(CYLINDER_SIDES):  # each slab's inner face at the hole's radius from its axis
        slab = model.geom(f"ring_{k:02d}")
        assert np.hypot(*slab.pos[:2]) - slab.size[0] == pytest.approx(0.012 + 0.0004)
    peg = model.geom("tool_geom")
    vertices = model.mesh_vert[model.mesh_vertadr[peg.dataid[0]]:][:model.mesh_vertnum[peg.dataid[0]]]
    np.testing.assert_allclose(np.hypot(vertices[:, 0], vertices[:, 1]), 0.012, rtol=1e-6)
    np.testing.assert_allclose(peg.pos, [0, 0, 0.035], atol=1e-9)  # still mounted on the flange, 0.07 long
    np.testing.assert_allclose(model.site("tool").pos, [0, 0, 0.07], atol=1e-9)  # the tip moved with the peg's end
    body = model.body("tool_tool").id
    np.testing.assert_allclose(np.sort(model.body_inertia[body]), np.sort(np.diag(0.2 * cylinder_tensor((0.012, 0.07)))),
                               rtol=1e-9)


@pytest.mark.parametrize("name, old, new, key, message", [
    ("peg", "    friction: 0.3\n    extra:", "    mass: 1.0\n    friction: 0.3\n    extra:", "objects.BoxWithHole-1.mass",
     "mocap body: it does not move"),
    ("push", "    shape: box\n    size: [0.07, 0.07, 0.05]", "    shape: right_triangle_prism\n    size: [0.07, 0.07, 0.05]",
     "objects.Pusher-1.shape", "exactly one mesh geom"),
    ("push", "  Home-1:\n    type: pose\n    shape: pose\n    size: []\n",
     "  Home-1:\n    type: pose\n    shape: pose\n    size: []\n    friction: 0.5\n", "objects.Home-1.friction",
     "needs a body or geom"),
    ("push", "    shape: box\n    size: [0.07, 0.07, 0.05]", "    shape: box\n    size: [0.07, 0.05]",
     "objects.Pusher-1.size", "a box has 3 sizes"),
    ("peg", "      hole_depth: 0.04\n", "      hole_depth: 0.06\n", "objects.BoxWithHole-1.size", "does not fit in the box"),
    ("peg_square", "      hole_depth: 0.04\n", "      hole_depth: 0.06\n", "objects.BoxWithHole-1.size", "does not fit in the box"),
    ("peg", "size: [0.015, 0.05]  ", "size: [0.025, 0.05]  ", "objects.BoxWithHole-1.size", "round hole .* does not fit"),
    ("peg", "    shape: cylinder\n    size: [0.015, 0.05]  ", "    shape: box\n    size: [0.03, 0.03, 0.05]  ",
     "objects.Peg-1.shape", "a box is drawn by exactly one box geom of body 'tool_tool'; it has tool_geom \\(mesh\\)"),
    ("peg_square", "    shape: box_with_hole\n", "    shape: box_with_round_hole\n", "objects.BoxWithHole-1.shape",
     "drawn by 21 box geoms .* it has 5 geoms"),
    ("peg", "    shape: cylinder\n    size: [0.015, 0.05]  ", "    shape: cylinder\n    size: [0.015, 0.05, 0.01]  ",
     "objects.Peg-1.size", "a cylinder has 2 sizes"),
])
def test_what_the_simulator_cannot_honour_is_an_error_naming_the_entry(tmp_path, name, old, new, key, message):
    with pytest.raises(ScenarioError, match=rf"{key} \(line \d+\): .*{message}"):
        edited(tmp_path, name, (old, new))


def _final_object(scn, params, seconds: float):
    """Final position (3,) and quaternion (4,) of the pushed prism after ``seconds`` of the push in
    the nominal world of start configuration 0 (friction as the model holds it)."""
    engine = NativeRollout(scn, plan_task(scn), worlds=1, episode_seconds=seconds)
    world = jax.tree.map(lambda x: np.asarray(x)[0], engine.worlds_per_config(jax.random.key(0), 1))
    world = world._replace(object_pos=engine.sampler.nominal_pos.copy(), friction=np.float32(np.nan))
    _, record = engine.trace(params, world)
    adr = engine.setup.bindings.slots[engine.setup.bindings.slot_of["ObjectToBePushed-1"]].qpos_adr
    return record.qpos[-1, adr:adr + 3], record.qpos[-1, adr + 3:adr + 7]


def test_a_heavier_prism_moves_less_under_the_same_push_and_other_physics_moves_it_otherwise(tmp_path):
    no_random = ("friction_range: [0.2, 0.25]", "friction_range: null")
    start = np.array([0.55, -0.20, 0.035])
    shipped_pos, shipped_quat = _final_object(edited(tmp_path / "a", "push", no_random), HAND_FOUND, 5.0)
    heavy_pos, _ = _final_object(edited(tmp_path / "b", "push", no_random, ("    mass: 2.5", "    mass: 12.0")), HAND_FOUND, 5.0)
    moved, heavy_moved = np.linalg.norm(shipped_pos - start), np.linalg.norm(heavy_pos - start)
    assert moved > 0.05 and heavy_moved < moved - 0.01, (moved, heavy_moved)
    com_pos, com_quat = _final_object(edited(tmp_path / "c", "push", no_random,
                                             ("com_offset: [-0.02, 0.04, -0.005]", "com_offset: [0.03, -0.06, -0.005]")),
                                      HAND_FOUND, 5.0)
    rough_pos, _ = _final_object(edited(tmp_path / "d", "push", no_random,
                                        ("    friction: 0.2\n    pose: {position: [0.55", "    friction: 0.6\n    pose: {position: [0.55")),
                                 HAND_FOUND, 5.0)
    assert np.linalg.norm(com_pos - shipped_pos) > 1e-3 or abs(float(np.dot(com_quat, shipped_quat))) < 1 - 1e-6
    assert np.linalg.norm(rough_pos - shipped_pos) > 1e-3


def test_a_tighter_hole_changes_the_insertion(tmp_path):
    # The same straight press (no search) onto the box at its nominal place: the arm lands the
    # peg about 0.7 mm off the hole's axis (the impedance controller's accuracy), inside the
    # shipped 1.5 mm clearance, on the rim of a 0.3 mm one.
    depths = []
    for clearance in ("0.0015", "0.0003"):
        scn = edited(tmp_path / clearance, "peg", ("hole_clearance: 0.0015", f"hole_clearance: {clearance}"))
        engine = NativeRollout(scn, plan_task(scn), worlds=1, episode_seconds=4.0)
        world = jax.tree.map(lambda x: np.asarray(x)[0], engine.worlds_per_config(jax.random.key(0), 1))
        world = world._replace(object_pos=engine.sampler.nominal_pos.copy())
        out = engine.run_worlds(np.array([[-5.0, 0.0, 0.0]]), jax.tree.map(lambda x: np.asarray(x)[None], world))
        depths.append(float(out.metrics["insertion_depth"][0, 0]))
    assert depths[0] > scn.success.depth > depths[1], depths


def test_a_process_compiles_a_scenarios_model_once(monkeypatch):
    """load_scenario builds the model to validate the YAML; the engines take copies of that build
    instead of compiling the scene again, and a copy changed by one engine (the native engine
    writes each world's friction into its model) leaves the others as built."""
    import mjxskill.sim.model as model_module
    from mjxskill.engine import build_rollout
    from mjxskill.task import plan_task

    compiled = []
    real = model_module.compile_model
    monkeypatch.setattr(model_module, "compile_model", lambda scn: compiled.append(scn) or real(scn))
    scn = load_scenario("push")
    task = plan_task(scn)
    rollouts = [build_rollout(scn, task, engine, worlds=1, episode_seconds=0.1, workers=1) for engine in ("native", "mjx")]
    try:
        assert compiled == [scn]
        native, mjx = rollouts
        assert native.mj_model is not mjx.mj_model
        native.mj_model.pair_friction[:] = 7.0
        assert not np.any(mjx.mj_model.pair_friction == 7.0) and not np.any(build_model(scn).pair_friction == 7.0)
    finally:
        for rollout in rollouts:
            rollout.close()
