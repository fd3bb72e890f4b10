"""Loading and validating a scenario YAML (the digital twin) into an immutable ``Scenario``.

``load_scenario("push")`` reads ``assets/scenarios/push.yaml``; ``load_scenario(path)`` any file.
Every invalid file fails with one ``ScenarioError`` naming the file, the key path and the line.
Loading also plans the scenario's default goal (``mjxskill.plan.plan_task``): the learnable
parameters (``Scenario.parameter_names``) are those the plan leaves open.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from mjxskill.ebt.from_plan import EXPANSIONS, PlanError
from mjxskill.pddl_gen import GoalError, check_atom, parse_literal
from mjxskill.scenario_schema import (
    REWARD_KINDS,
    Optimizer,
    Pose,
    Randomization,
    Reward,
    Robot,
    Scenario,
    Skill,
    SkillParameter,
    Success,
    WorldObject,
    frozen_array,
    frozen_mapping,
)
from mjxskill.yaml_fields import Field, ScenarioError, compose_file

SCENARIO_DIR = Path(__file__).resolve().parent.parent / "assets" / "scenarios"

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
            f"unknown task {text!r}: no {path.name} in {SCENARIO_DIR} "
            f"(available: {', '.join(available_scenarios()) or 'none'}); pass a YAML path for your own"
        )
    return path


def load_scenario(name_or_path: str | Path, *, solve: Callable[[str, str], Sequence[str]] | None = None) -> Scenario:
    """Reads, validates and plans a scenario.

    name_or_path: a scenario name ("push", "peg") or the path of a YAML file.
    solve: the planner ``(domain, problem) -> ["(action arg ...)", ...]``; default
    ``mjxskill.planner.solve``.
    """
    path = scenario_path(name_or_path)
    root = compose_file(path)
    top = root.mapping(
        required=(
            "name", "scene", "gravity", "episode_seconds", "bt_hz", "control_hz", "types", "predicates",
            "robot", "objects", "skills", "goal", "objectives", "rewards", "success", "randomization",
            "optimizer",
        ),
        optional=("manual_parameters",),
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
    skills = frozen_mapping((name, _skill(name, field, types, predicates)) for name, field in top["skills"].items())
    if not skills:
        top["skills"].fail("the skill library is empty")
    object_names = set(objects)
    objectives = top["objectives"].strings()
    _no_duplicates(top["objectives"], objectives, "objective")
    bt_hz = top["bt_hz"].integer(minimum=1)
    control_hz = top["control_hz"].integer(minimum=1)
    if control_hz % bt_hz:
        top["control_hz"].fail(f"control_hz {control_hz} must be a multiple of bt_hz {bt_hz}")
    scn = Scenario(
        name=top["name"].string(),
        source=str(path),
        scene=str((path.parent / top["scene"].string()).resolve()),
        gravity=top["gravity"].boolean(),
        episode_seconds=top["episode_seconds"].number(positive=True),
        bt_hz=bt_hz,
        control_hz=control_hz,
        types=types,
        predicates=predicates,
        objects=objects,
        robot=robot,
        skills=skills,
        goal=top["goal"].string(),
        rewards=_rewards(top["rewards"], objectives, object_names),
        objective_names=tuple(objectives),
        success=_success(top["success"], object_names),
        randomization=_randomization(top["randomization"], object_names),
        optimizer=_optimizer(top["optimizer"]),
        manual_parameters=frozen_mapping({}),
        task=None,
    )
    if not scn.name.replace("-", "").replace("_", "").isalnum():
        top["name"].fail(f"{scn.name!r} is not usable as a PDDL name (letters, digits, - and _)")

    from mjxskill.plan import plan_task  # plan imports this module's types

    try:
        task = plan_task(scn, solve=solve)
    except (GoalError, PlanError) as err:  # e.g. no plan: the goal is what cannot be reached
        top["goal"].fail(str(err))
    manual = _manual_parameters(top.get("manual_parameters"), task)
    return dataclasses.replace(scn, task=task, manual_parameters=manual)


# -- sections ---------------------------------------------------------------------------------
def _no_duplicates(field: Field, names, what: str) -> None:
    seen = set()
    for item, name in zip(field.seq(), names):
        if name.lower() in seen:
            item.fail(f"duplicate {what} name {name!r}")
        seen.add(name.lower())


def _pddl_name(field: Field, name: str) -> str:
    if not name.replace("-", "").replace("_", "").isalnum() or not name[0].isalpha():
        field.fail(f"{name!r} is not a PDDL name (a letter, then letters, digits, - or _)")
    return name.lower()


def _types(field: Field):
    parents = {}
    for name, parent in field.items():
        key = _pddl_name(parent, name)
        if key == "object":
            parent.fail("'object' is PDDL's root type; name your types differently")
        if key in parents:
            parent.fail(f"duplicate type {name!r}")
        parents[key] = None if parent.is_null() else parent.string().lower()
    for (name, parent), (_, parent_field) in zip(parents.items(), field.items()):
        if parent is not None and parent not in parents:
            parent_field.fail(f"unknown parent type {parent!r} (types: {', '.join(parents)})")
        seen = {name}
        while parent is not None:  # a cycle would make every type its own ancestor
            if parent in seen:
                parent_field.fail(f"type {name!r} is its own ancestor")
            seen.add(parent)
            parent = parents[parent]
    return frozen_mapping(parents)


def _predicates(field: Field, types):
    predicates = {}
    for name, args in field.items():
        key = _pddl_name(args, name)
        if key in predicates:
            args.fail(f"duplicate predicate {name!r}")
        arg_types = tuple(t.lower() for t in args.strings())
        for item, type_ in zip(args.seq(), arg_types):
            if type_ not in types:
                item.fail(f"unknown type {type_!r} (types: {', '.join(types)})")
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
            where.fail(f"duplicate name {name!r}: object names must differ in more than case")
        type_ = type_field.string().lower()
        if type_ not in types:
            type_field.fail(f"unknown type {type_!r} (types: {', '.join(types)})")
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
            item.fail(f"{text!r} is not a PDDL fact like (pushable box-1)")
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
    rows = field.matrix(7)
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
    limits_deg = np.array(f["joint_limits_deg"].vector(7))
    if np.any(limits_deg <= 0):
        f["joint_limits_deg"].fail("joint limits must be positive (degrees, symmetric)")
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
        nullspace_stiffness=f["nullspace_stiffness"].number(nonnegative=True),
        default_stiffness=_nonnegative_vector(f["default_stiffness"], 6),
        relations=_relations(f.get("relations"), types, predicates, names),
    )


def _configs_row(field: Field, limits) -> np.ndarray:
    values = field.vector(7)
    for j, q in enumerate(values):
        if abs(q) > limits[j]:
            field.seq()[j].fail(f"joint {j + 1} angle {q} rad is outside the joint limit +-{limits[j]:.4f} rad")
    return frozen_array(values)


def _nonnegative_vector(field: Field, length: int) -> np.ndarray:
    values = field.vector(length)
    for item, v in zip(field.seq(), values):
        if v < 0:
            item.fail(f"expected a value >= 0, got {v}")
    return frozen_array(values)


_OBJECT_KEYS = (
    "type", "mjcf_body", "shape", "size", "mass", "friction", "com_offset", "pose", "approach_offset",
    "extra", "relations",
)


def _object(name: str, field: Field, types, predicates, names) -> WorldObject:
    f = field.mapping(required=("type", "shape", "size", "pose"), optional=_OBJECT_KEYS)
    pose = f["pose"].mapping(required=("position", "rpy_deg"))
    size = f["size"].vector()
    for item, v in zip(f["size"].seq(), size):
        if v < 0:
            item.fail(f"sizes are lengths >= 0 (m), got {v}")
    optional_number = lambda key: None if key not in f or f[key].is_null() else f[key].number(positive=True)  # noqa: E731
    extra = f["extra"].items() if "extra" in f else []
    return WorldObject(
        name=name,
        type=f["type"].string().lower(),
        pose=Pose(frozen_array(pose["position"].vector(3)), frozen_array(pose["rpy_deg"].vector(3))),
        mjcf_body=None if "mjcf_body" not in f or f["mjcf_body"].is_null() else f["mjcf_body"].string(),
        shape=f["shape"].string(),
        size=frozen_array(size),
        mass=optional_number("mass"),
        friction=optional_number("friction"),
        com_offset=frozen_array(f["com_offset"].vector(3) if "com_offset" in f else (0.0, 0.0, 0.0)),
        approach_offset=frozen_array(f["approach_offset"].vector(3) if "approach_offset" in f else (0.0, 0.0, 0.0)),
        extra=frozen_mapping((k, v.number()) for k, v in extra),
        relations=_relations(f.get("relations"), types, predicates, names),
    )


def _skill(name: str, field: Field, types, predicates) -> Skill:
    if name not in EXPANSIONS:
        field.fail(f"unknown skill {name!r}: no expansion into a behavior tree (known: {', '.join(EXPANSIONS)})")
    f = field.mapping(required=("parameters", "preconditions", "postconditions"), optional=("holdconditions",))
    parameters = []
    for pname, pfield in f["parameters"].items():
        parameters.append(_skill_parameter(pname, pfield, types))
    by_name = {p.name: p for p in parameters}
    for needed, kind in EXPANSIONS[name][1].items():
        if needed not in by_name:
            f["parameters"].fail(f"skill {name} needs a parameter {needed!r} ({kind})")
        p = by_name[needed]
        if kind == "float" and p.type != "float" or kind == "vector6" and (p.type != "vector" or len(p.default) != 6):
            f["parameters"].items()[list(by_name).index(needed)][1].fail(
                f"skill {name} reads {needed!r} as a {'6-vector' if kind == 'vector6' else 'number'}"
            )
    variables = {f"?{p.name.lower()}": p.type for p in parameters if p.plan}
    conditions = {}
    for key in ("preconditions", "holdconditions", "postconditions"):
        texts = []
        for item in f[key].seq() if key in f else []:
            text = item.string()
            literal = parse_literal(text)
            if literal is None:
                item.fail(f"{text!r} is not a PDDL literal like (at ?peg ?box) or (not (at ?peg ?box))")
            problem = check_atom(literal[1], literal[2], predicates, types, variables, what="parameter")
            if problem:
                item.fail(f"{problem} (plan parameters: {', '.join(variables) or 'none'})")
            texts.append(text)
        conditions[key] = tuple(texts)
    if not conditions["postconditions"]:
        f["postconditions"].fail(f"skill {name} has no postconditions, so no plan can use it")
    return Skill(name, tuple(parameters), conditions["preconditions"], conditions["holdconditions"], conditions["postconditions"])


def _skill_parameter(name: str, field: Field, types) -> SkillParameter:
    f = field.mapping(optional=("type", "plan", "unit", "default", "bounds", "learnable", "description"))
    if "type" not in f:
        field.fail("missing key 'type'")
    plan = f["plan"].boolean() if "plan" in f else False
    description = f["description"].string() if "description" in f else ""
    if plan:
        type_ = f["type"].string().lower()
        if type_ not in types:
            f["type"].fail(f"unknown type {type_!r} for a plan parameter (types: {', '.join(types)})")
        for key in ("default", "bounds", "learnable"):
            if key in f:
                f[key].fail(f"a plan parameter (set by the planner) has no {key}")
        return SkillParameter(name, type_, True, description=description)
    type_ = f["type"].string(choices=("float", "vector"))
    unit = f["unit"].string() if "unit" in f else ""
    if "default" not in f:
        field.fail("missing key 'default'")
    learnable = f["learnable"].boolean() if "learnable" in f else False
    if type_ == "vector":
        if learnable or "bounds" in f:
            field.fail("vector parameters cannot be learnable")
        return SkillParameter(name, type_, False, unit, f["default"].vector(), None, False, description)
    default = f["default"].number()
    bounds = None
    if "bounds" in f:
        lower, upper = f["bounds"].vector(2)
        if lower > upper:
            f["bounds"].fail(f"lower bound {lower} is above the upper bound {upper}")
        if not lower <= default <= upper:
            f["default"].fail(f"default {default} is outside the bounds [{lower}, {upper}]")
        bounds = (lower, upper)
    if learnable and bounds is None:
        field.fail("a learnable parameter needs bounds: [lower, upper]")
    return SkillParameter(name, type_, False, unit, default, bounds, learnable, description)


def _rewards(field: Field, objectives, object_names) -> tuple[Reward, ...]:
    rewards, used = [], set()
    for item in field.seq():
        f = item.mapping(
            required=("name", "kind", "objective", "weight", "constants"), optional=("object", "target", "target_offset")
        )
        name = f["name"].string()
        if name in {r.name for r in rewards}:
            f["name"].fail(f"duplicate reward name {name!r}")
        kind = f["kind"].string(choices=REWARD_KINDS)
        objective = f["objective"].string()
        if objective not in objectives:
            f["objective"].fail(f"unknown objective {objective!r} (objectives: {', '.join(objectives)})")
        used.add(objective)
        constants = dict((k, v.number()) for k, v in f["constants"].mapping(required=REWARD_KINDS[kind]).items())
        for key in ("object", "target"):
            if key in f and f[key].string() not in object_names:
                f[key].fail(f"unknown object {f[key].string()!r} (objects: {', '.join(sorted(object_names))})")
        if kind == "object_pose_divergence" and not ("object" in f and "target" in f):
            item.fail("object_pose_divergence needs 'object' and 'target'")
        if kind in ("exp_ee_to_goal", "ee_distance_to_box") and "target" not in f:
            item.fail(f"{kind} needs a 'target' object")
        rewards.append(
            Reward(
                name, kind, f["weight"].number(), objective, frozen_mapping(constants),
                f["object"].string() if "object" in f else None,
                f["target"].string() if "target" in f else None,
                frozen_array(f["target_offset"].vector(3)) if "target_offset" in f else None,
            )
        )
    for objective in objectives:
        if objective not in used:
            field.fail(f"objective {objective!r} has no reward")
    return tuple(rewards)


def _success(field: Field, object_names) -> Success:
    kind = field.mapping(required=("kind",), optional=("object", "target", "position_tolerance", "orientation_tolerance_deg", "depth"))["kind"].string(choices=("object_at_pose", "inserted"))
    extra = ("position_tolerance", "orientation_tolerance_deg") if kind == "object_at_pose" else ("depth",)
    f = field.mapping(required=("kind", "object", "target", *extra))
    for key in ("object", "target"):
        if f[key].string() not in object_names:
            f[key].fail(f"unknown object {f[key].string()!r} (objects: {', '.join(sorted(object_names))})")
    values = {key: f[key].number(positive=True) for key in extra}
    return Success(kind, f["object"].string(), f["target"].string(), **values)


def _randomization(field: Field, object_names) -> Randomization:
    f = field.mapping(required=("n_worlds", "xy_sigma"), optional=("clip_sigmas", "friction_range"))
    sigma = {}
    for name, value in f["xy_sigma"].items():
        if name not in object_names:
            value.fail(f"unknown object {name!r} (objects: {', '.join(sorted(object_names))})")
        sigma[name] = value.number(nonnegative=True)
    clip = None if "clip_sigmas" not in f or f["clip_sigmas"].is_null() else f["clip_sigmas"].number(positive=True)
    friction = None
    if "friction_range" in f and not f["friction_range"].is_null():
        low, high = f["friction_range"].vector(2)
        if not 0 <= low <= high:
            f["friction_range"].fail(f"expected 0 <= low <= high, got [{low}, {high}]")
        friction = (low, high)
    return Randomization(frozen_mapping(sigma), clip, friction, f["n_worlds"].integer(minimum=1))


def _optimizer(field: Field) -> Optimizer:
    f = field.mapping(required=("budget", "batch_size", "n_init", "seed", "repetitions"))
    opt = Optimizer(
        budget=f["budget"].integer(minimum=1),
        batch_size=f["batch_size"].integer(minimum=1),
        n_init=f["n_init"].integer(minimum=1),
        seed=f["seed"].integer(minimum=0),
        repetitions=f["repetitions"].integer(minimum=1),
    )
    if opt.n_init > opt.budget:
        f["n_init"].fail(f"n_init {opt.n_init} exceeds the budget {opt.budget}")
    return opt


def _manual_parameters(field: Field | None, task):
    if field is None:
        return frozen_mapping({})
    names = [p.name for p in task.parameters]
    sets = {}
    for set_name, values_field in field.items():
        values = dict(values_field.items())
        for key, item in values.items():
            if key not in names:
                item.fail(f"{key!r} is not a learnable parameter of the plan (parameters: {', '.join(names)})")
        vector = []
        for p in task.parameters:
            if p.name not in values:
                values_field.fail(f"missing key {p.name!r}")
            v = values[p.name].number()
            if not p.lower <= v <= p.upper:
                values[p.name].fail(f"{v} is outside the bounds [{p.lower}, {p.upper}] {p.unit}")
            vector.append(v)
        sets[set_name] = frozen_array(vector)
    return frozen_mapping(sets)
