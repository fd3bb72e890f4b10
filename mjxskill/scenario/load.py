"""Loading and validating a scenario YAML (the digital twin) into an immutable ``Scenario``.

``load_scenario("push")`` reads the shipped ``assets/scenarios/push.yaml``; ``load_scenario(path)`` any file.
Every invalid file fails with one ``ScenarioError`` naming the file, the key path and the line.
Loading plans nothing: ``mjxskill.task.plan_task`` turns a goal into a plan, an eBT and the
learnable parameters. This module reads the top level, the PDDL vocabulary (types,
predicates, relations), the robot and the objects; ``skills`` and ``sections`` read the rest.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mjxskill.errors import GoalError, ScenarioError, listing, quote
from mjxskill.planner.world_pddl import check_atom, goal_literals, parse_literal
from mjxskill.scenario.fields import Field, compose_file
from mjxskill.scenario.scene_refs import check_scene
from mjxskill.scenario.domain import ANGLE_DEG, EXTRA, FRICTION, JOINT_ANGLE, JOINT_LIMIT_DEG, MASS, POSITION, SIZE, STIFFNESS
from mjxskill.scenario.schema import MAX_EPISODE_SECONDS, Pose, Robot, Scenario, WorldObject, frozen_array, frozen_mapping
from mjxskill.scenario.vocabulary import SHAPES
from mjxskill.scenario.calibration import calibrated, calibration
from mjxskill.scenario.sections import optimizer, pick, randomization, rewards, success
from mjxskill.scenario.skills import (
    manual_parameters, parameter_priors, skill, skill_fields, skill_parameter_overrides,
)
from mjxskill.sim.model import build_model
from mjxskill.sim.scene import asset_path

# the shipped scenarios (mjxskill.assets: the checkout's assets/, or inside the installed package)
SCENARIO_DIR = asset_path("scenarios")

__all__ = ["SCENARIO_DIR", "ScenarioError", "available_scenarios", "load_scenario", "scenario_path"]


def available_scenarios() -> tuple[str, ...]:
    return tuple(sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml")))


def scenario_path(name_or_path: str | Path) -> Path:
    """``"push"`` -> assets/scenarios/push.yaml; a path (with a suffix or a slash) as given."""
    text = str(name_or_path)
    if isinstance(name_or_path, Path) or text.endswith((".yaml", ".yml")) or "/" in text or "\\" in text:
        return Path(name_or_path)
    path = SCENARIO_DIR / f"{text}.yaml"
    if not path.exists():
        raise ScenarioError(
            f"unknown task {quote(text)}: no {path.name} in {SCENARIO_DIR} "
            f"(available: {listing(available_scenarios()) or 'none'}); pass a YAML path for your own"
        )
    return path


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Reads and validates a scenario.

    name_or_path: a scenario name ("push", "peg") or the path of a YAML file.
    """
    path = scenario_path(name_or_path)
    root = compose_file(path)
    top = root.mapping(
        required=(
            "name", "scene", "gravity", "episode_seconds", "bt_hz", "control_hz", "types", "predicates",
            "robot", "objects", "goal", "objectives", "rewards", "success", "randomization", "optimizer",
        ),
        optional=("manual_parameters", "parameter_priors", "skills", "skill_library", "skill_parameters", "pick",
                  "calibration", "calibrated"),
    )
    types = _types(top["types"])
    predicates = _predicates(top["predicates"], types)
    robot_field = top["robot"]
    objects_field = top["objects"]
    # PDDL names first: relations of any object may mention any other.
    names = _object_names(robot_field, objects_field, types)
    robot = _robot(robot_field, types, predicates, names)
    objects = frozen_mapping(
        (name, _object(name, field, types, predicates, names)) for name, field in objects_field.items()
    )
    libraries = _skill_libraries(top, path)
    entries = skill_fields(top, [root for _, root in libraries])
    overrides = skill_parameter_overrides(top.get("skill_parameters"), entries)
    skills = frozen_mapping((name, _skill(name, field, types, predicates, path, overrides.get(name)))
                            for name, field in entries)
    if not skills:
        (top["skills"] if "skills" in top else root).fail("the skill library is empty (skills: or skill_library:)")
    object_names = set(objects)
    objectives = top["objectives"].strings()
    _no_duplicates(top["objectives"], objectives, "objective")
    bt_hz = top["bt_hz"].integer(minimum=1)
    control_hz = top["control_hz"].integer(minimum=1)
    if control_hz % bt_hz:
        top["control_hz"].fail(f"control_hz {control_hz} must be a multiple of bt_hz {bt_hz}")
    name = top["name"].pddl_name(what="a scenario name (the PDDL domain's)")
    scn = Scenario(
        name=name,
        source=str(path),
        libraries=tuple(str(p) for p, _ in libraries),
        scene=str((path.parent / top["scene"].string()).resolve()),
        gravity=top["gravity"].boolean(),
        episode_seconds=top["episode_seconds"].number(positive=True, maximum=MAX_EPISODE_SECONDS),
        bt_hz=bt_hz,
        control_hz=control_hz,
        types=types,
        predicates=predicates,
        objects=objects,
        robot=robot,
        skills=skills,
        goal=top["goal"].string(),
        rewards=rewards(top["rewards"], objectives, object_names),
        objective_names=tuple(objectives),
        success=success(top["success"], objects),
        randomization=randomization(top["randomization"], object_names),
        optimizer=optimizer(top["optimizer"]),
        manual_parameters=manual_parameters(top.get("manual_parameters"), skills),
        parameter_priors=parameter_priors(top.get("parameter_priors"), skills),
        pick=pick(top.get("pick")),
        calibration=calibration(top.get("calibration"), objects),
        calibrated=calibrated(top.get("calibrated")),
        locations=frozen_mapping(_locations(top, robot_field, objects_field)),
    )
    try:  # the goal's syntax and names (planning it is mjxskill.task's)
        goal_literals(scn, scn.goal)
    except GoalError as err:
        top["goal"].fail(str(err))
    refs = _scene_fields(top, robot_field, objects_field)
    geoms = {key: refs.pop(key) for key in list(refs) if key.endswith(".mjcf_geom")}
    check_scene(Path(scn.scene), refs.pop("scene"), refs.pop("robot.tool_site"), refs, geoms)
    # The physics the YAML gives is written into the MJCF model: what cannot be is an error now,
    # naming the entry (mjxskill.sim.model), not a run that silently simulates something else.
    build_model(scn)
    return scn


def _skill(name: str, field: Field, types, predicates, path: Path, overrides=None):
    """A skill (with the scenario's ``skill_parameters`` for it); one of a library is checked
    against the including scenario's vocabulary, and its errors say so (the library is right for
    another scenario)."""
    try:
        return skill(name, field, types, predicates, overrides)
    except ScenarioError as err:
        if field.source == str(path) or str(err).startswith(f"{path}:"):  # the scenario's own entry
            raise
        raise ScenarioError(f"{err} (as included by {path}, whose types and predicates it uses)") from None


def _skill_libraries(top, path: Path) -> list[tuple[Path, Field]]:
    """(path, root Field) of each file ``skill_library`` names (one path or a list, relative to
    the scenario file), read like the scenario. Only a regular file named ``*.yaml`` or ``*.yml``
    is read: a path to any other file (``/etc/passwd``) is refused before it is opened, so that no
    error can show what it holds."""
    if "skill_library" not in top:
        return []
    field = top["skill_library"]
    items = field.seq() if field.node.tag.endswith(":seq") else [field]
    libraries = []
    for item in items:
        library = (path.parent / item.string()).resolve()
        try:
            regular = library.is_file()
        except OSError as err:  # a name too long, a loop of links
            item.fail(f"the skill library {quote(str(library), 300)} cannot be read ({err.strerror})")
        if not regular:
            item.fail(f"the skill library {quote(str(library), 300)} is not a file (paths are relative to the scenario "
                      "file)")
        if library.suffix.lower() not in (".yaml", ".yml"):
            item.fail(f"the skill library {quote(str(library), 300)} is not a YAML file (.yaml or .yml); refusing to "
                      "read it")
        libraries.append((library, compose_file(library, what="skill library")))
    return libraries


def _scene_fields(top, robot: Field, objects: Field) -> dict[str, Field]:
    """The scene and the entries naming things in it: key path -> Field."""
    fields = {"scene": top["scene"], "robot.tool_site": robot.mapping(optional=_ROBOT_KEYS)["tool_site"]}
    for name, field in objects.items():
        entries = field.mapping(optional=_OBJECT_KEYS)
        for key in ("mjcf_body", "mjcf_geom"):
            if key in entries:
                fields[f"objects.{name}.{key}"] = entries[key]
    return fields


def _locations(top, robot: Field, objects: Field) -> dict[str, str]:
    """key path -> "file: key path (line N)" of the entries checked after loading: the goal,
    the scene references and every object entry (the model builder names them)."""
    fields = {"goal": top["goal"], **_scene_fields(top, robot, objects)}
    for name, field in objects.items():
        for key, entry in field.mapping(optional=_OBJECT_KEYS).items():
            fields[f"objects.{name}.{key}"] = entry
            if key == "extra" and entry.node.tag.endswith(":map"):
                fields.update((f"objects.{name}.extra.{k}", v) for k, v in entry.items())
    return {key: f.where() for key, f in fields.items()}


# -- sections ---------------------------------------------------------------------------------
def _no_duplicates(field: Field, names, what: str) -> None:
    seen = set()
    for item, name in zip(field.seq(), names):
        if name.lower() in seen:
            item.fail(f"duplicate {what} name {quote(name)}")
        seen.add(name.lower())


def _pddl_name(field: Field, name: str) -> str:
    return field.pddl_name(name, "a PDDL name").lower()


def _types(field: Field):
    parents: dict[str, str | None] = {}
    for name, item in field.items():
        key = _pddl_name(item, name)
        if key == "object":
            item.fail("'object' is PDDL's root type; name your types differently")
        if key in parents:
            item.fail(f"duplicate type {quote(name)}")
        parents[key] = None if item.is_null() else item.string().lower()
    for (name, parent), (_, parent_field) in zip(parents.items(), field.items()):
        if parent is not None and parent not in parents:
            parent_field.fail(f"unknown parent type {quote(parent)} (types: {listing(parents)})")
        seen = {name}
        while parent is not None:  # a cycle would make every type its own ancestor
            if parent in seen:
                parent_field.fail(f"type {quote(name)} is its own ancestor")
            seen.add(parent)
            parent = parents[parent]
    return frozen_mapping(parents)


def _predicates(field: Field, types):
    predicates = {}
    for name, args in field.items():
        key = _pddl_name(args, name)
        if key in predicates:
            args.fail(f"duplicate predicate {quote(name)}")
        arg_types = tuple(t.lower() for t in args.strings())
        for item, type_ in zip(args.seq(), arg_types):
            if type_ not in types:
                item.fail(f"unknown type {quote(type_)} (types: {listing(types)})")
        predicates[key] = arg_types
    return frozen_mapping(predicates)


def _object_names(robot: Field, objects: Field, types) -> dict[str, str]:
    """PDDL name -> type of every object and the robot; names unique ignoring case."""
    robot_fields = robot.mapping(required=_ROBOT_KEYS[:-1], optional=("relations",))
    entries = [(robot_fields["name"].string(), robot_fields["name"], robot_fields["type"])]
    for name, field in objects.items():
        fields = field.mapping(required=("type", "shape", "size", "pose"), optional=_OBJECT_KEYS)
        entries.append((name, field, fields["type"]))
    names: dict[str, str] = {}
    for name, where, type_field in entries:
        key = _pddl_name(where, name)
        if key in names:
            where.fail(f"duplicate name {quote(name)}: object names must differ in more than case")
        type_ = type_field.string().lower()
        if type_ not in types:
            type_field.fail(f"unknown type {quote(type_)} (types: {listing(types)})")
        names[key] = type_
    return names


def _relations(field: Field | None, types, predicates, names) -> tuple[str, ...]:
    if field is None:
        return ()
    relations = []
    for item in field.seq():
        text = item.string()
        literal = parse_literal(text)
        if literal is None or not literal[0]:
            item.fail(f"{quote(text)} is not a PDDL fact like (pushable box-1)")
        problem = check_atom(literal[1], literal[2], predicates, types, names)
        if problem:
            item.fail(problem)
        relations.append(f"({' '.join((literal[1], *literal[2]))})")
    return tuple(relations)


_ROBOT_KEYS = (
    "name", "type", "tool_site", "home", "joint_limits_deg", "nullspace_stiffness", "default_stiffness",
    "start_configs", "eval_configs", "relations",
)


def _configs(field: Field, limits: np.ndarray, at_least: int) -> np.ndarray:
    rows = field.matrix(7, JOINT_ANGLE)
    if len(rows) < at_least:
        field.fail(f"expected at least {at_least} configurations of 7 joint angles (rad), got {len(rows)}")
    for i, row in enumerate(rows):
        for j, q in enumerate(row):
            if abs(q) > limits[j]:
                field.seq()[i].seq()[j].fail(
                    f"joint {j + 1} angle {q} rad is outside the joint limit +-{limits[j]:.4f} rad"
                )
    return frozen_array(rows)


def _robot(field: Field, types, predicates, names) -> Robot:
    f = field.mapping(required=_ROBOT_KEYS[:-1], optional=("relations",))
    limits_deg = np.array(f["joint_limits_deg"].vector(7, JOINT_LIMIT_DEG))
    limits = np.deg2rad(limits_deg)
    home = _configs_row(f["home"], limits)
    return Robot(
        name=f["name"].string(),
        type=f["type"].string().lower(),
        tool_site=f["tool_site"].string(),
        home=home,
        joint_limits=frozen_array([-limits, limits]),
        start_configs=_configs(f["start_configs"], limits, 1),
        eval_configs=_configs(f["eval_configs"], limits, 0),
        nullspace_stiffness=f["nullspace_stiffness"].number(STIFFNESS),
        default_stiffness=frozen_array(f["default_stiffness"].vector(6, STIFFNESS)),
        relations=_relations(f.get("relations"), types, predicates, names),
    )


def _configs_row(field: Field, limits) -> np.ndarray:
    values = field.vector(7, JOINT_ANGLE)
    for j, q in enumerate(values):
        if abs(q) > limits[j]:
            field.seq()[j].fail(f"joint {j + 1} angle {q} rad is outside the joint limit +-{limits[j]:.4f} rad")
    return frozen_array(values)


_OBJECT_KEYS = (
    "type", "mjcf_body", "mjcf_geom", "shape", "size", "mass", "friction", "com_offset", "pose", "approach_offset",
    "extra", "relations",
)


def _object(name: str, field: Field, types, predicates, names) -> WorldObject:
    f = field.mapping(required=("type", "shape", "size", "pose"), optional=_OBJECT_KEYS)
    pose = f["pose"].mapping(required=("position", "rpy_deg"))
    shape = f["shape"].string(choices=SHAPES)
    kind = SHAPES[shape]
    name_of = lambda key: None if key not in f or f[key].is_null() else f[key].string()  # noqa: E731
    body, geom = name_of("mjcf_body"), name_of("mjcf_geom")
    size = _size(f["size"], shape, kind.size, plane=geom is not None)
    if body is not None and geom is not None:
        f["mjcf_geom"].fail("an object is an MJCF body or a geom of the world body, not both")
    optional_number = lambda key, domain: None if key not in f or f[key].is_null() else f[key].number(domain)  # noqa: E731
    # Physics the simulator takes from the YAML (mjxskill.sim.model) needs something to write it into.
    for key in ("mass", "com_offset"):
        if key in f and not f[key].is_null() and body is None:
            f[key].fail(f"{key} needs a body to simulate it (mjcf_body); {name} has none")
    if "friction" in f and not f["friction"].is_null() and body is None and geom is None:
        f["friction"].fail(f"friction needs a body or geom to simulate it (mjcf_body or mjcf_geom); {name} has neither")
    extra = f["extra"].mapping(required=kind.extra) if "extra" in f else {}
    if kind.extra and "extra" not in f:
        f["shape"].fail(f"a {shape} needs extra: {{{listing(f'{k}: ...' for k in kind.extra)}}}")
    return WorldObject(
        name=name,
        type=f["type"].string().lower(),
        pose=Pose(frozen_array(pose["position"].vector(3, POSITION)), frozen_array(pose["rpy_deg"].vector(3, ANGLE_DEG))),
        mjcf_body=body,
        shape=shape,
        size=frozen_array(size),
        mass=optional_number("mass", MASS),
        friction=optional_number("friction", FRICTION),
        com_offset=frozen_array(f["com_offset"].vector(3, POSITION) if "com_offset" in f else (0.0, 0.0, 0.0)),
        approach_offset=frozen_array(f["approach_offset"].vector(3, POSITION) if "approach_offset" in f
                                     else (0.0, 0.0, 0.0)),
        extra=frozen_mapping((k, v.number(EXTRA)) for k, v in extra.items()),
        relations=_relations(f.get("relations"), types, predicates, names),
        mjcf_geom=geom,
    )


def _size(field: Field, shape: str, count: int, plane: bool) -> tuple[float, ...]:
    """``size``: ``count`` lengths in ``SIZE`` (m); an object that is a geom of the world body
    (``plane``) may have height 0: a plane (``mjxskill.sim.model`` checks which it is)."""
    items = field.seq()
    if len(items) != count:
        field.fail(f"a {shape} has {count} sizes (m), got {len(items)}")
    size = []
    for i, item in enumerate(items):
        if plane and i == 2 and item.number() == 0:
            size.append(0.0)
        else:
            size.append(item.number(SIZE))
    return tuple(size)
