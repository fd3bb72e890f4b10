"""The skill library and the operators' parameter sets of a scenario YAML.

Skills come from the scenario's ``skills`` and from the files its ``skill_library`` names (a
file of skills that many scenarios include: ``skills:`` at its top); a skill is its PDDL
action (parameters, pre-, hold- and postconditions) and its behavior tree (``tree``, a
template over the primitive library read by ``mjxskill.scenario.skill_tree``). A scenario's ``skill_parameters`` change the library's
parameters for that scenario (``skill_parameter_overrides``): a constant it makes learnable, a
default or bounds of its own.
"""

from __future__ import annotations

from typing import Mapping

from mjxskill.errors import listing, quote
from mjxskill.planner.world_pddl import check_atom, parse_literal
from mjxskill.scenario.fields import Field
from mjxskill.scenario.schema import ManualSet, ParameterPrior, Skill, SkillParameter, frozen_mapping
from mjxskill.scenario.domain import MIN_PRIOR_STD_SHARE, PARAMETER
from mjxskill.scenario.skill_tree import read_tree


def skill(name: str, field: Field, types, predicates, overrides: dict | None = None) -> Skill:
    """One entry of ``skills``: its parameters, PDDL conditions and tree. overrides: parameter
    name -> the scenario's ``skill_parameters`` entry for it (``skill_parameter_overrides``)."""
    field.pddl_name(name, "a skill name")
    f = field.mapping(required=("parameters", "preconditions", "postconditions", "tree"), optional=("holdconditions",))
    parameters = []
    for pname, pfield in f["parameters"].items():
        parameters.append(_skill_parameter(pname, pfield, types, (overrides or {}).get(pname)))
    by_name = {p.name: p for p in parameters}
    tree = read_tree(f["tree"], by_name)
    variables = {f"?{p.name.lower()}": p.type for p in parameters if p.plan}
    conditions = {}
    for key in ("preconditions", "holdconditions", "postconditions"):
        texts = []
        for item in f[key].seq() if key in f else []:
            text = item.string()
            literal = parse_literal(text)
            if literal is None:
                item.fail(f"{quote(text)} is not a PDDL literal like (at ?peg ?box) or (not (at ?peg ?box))")
            problem = check_atom(literal[1], literal[2], predicates, types, variables, what="parameter")
            if problem:
                item.fail(f"{problem} (plan parameters: {listing(variables) or 'none'})")
            texts.append(text)
        conditions[key] = tuple(texts)
    if not conditions["postconditions"]:
        f["postconditions"].fail(f"skill {name} has no postconditions, so no plan can use it")
    return Skill(name, tuple(parameters), conditions["preconditions"], conditions["holdconditions"],
                 conditions["postconditions"], tree)


def skill_fields(top: Mapping[str, Field], library_files: list) -> list[tuple[str, Field]]:
    """(name, Field) of every skill: those of each library file in ``library_files`` (root
    Fields, in order), then the scenario's own ``skills``; a name defined twice is an error
    naming both places."""
    entries: list[tuple[str, Field]] = []
    for root in library_files:
        entries += root.mapping(required=("skills",))["skills"].items()
    if "skills" in top:
        entries += top["skills"].items()
    seen: dict[str, Field] = {}
    for name, field in entries:
        if name in seen:
            field.fail(f"skill {quote(name)} is defined twice; the first is at {seen[name].where()}")
        seen[name] = field
    return entries


OVERRIDABLE = ("default", "bounds", "learnable")  # what a scenario's skill_parameters may change


def skill_parameter_overrides(field: Field | None, entries: list[tuple[str, Field]]) -> dict[str, dict[str, Field]]:
    """``skill_parameters``: ``"<Skill>.<parameter>": {default, bounds, learnable}`` (any of the
    three), the scenario's own values for a parameter of a skill it includes, e.g. a constant of
    the library made learnable with bounds. ``entries``: (name, Field) of every skill
    (``skill_fields``). Returns skill name -> parameter name -> the entry's Field; the values are
    checked with the skill (``skill``), each error naming the scenario's entry."""
    if field is None:
        return {}
    skills = dict(entries)
    out: dict[str, dict[str, Field]] = {}
    for key, item in field.items():
        skill_name, dot, name = key.partition(".")
        if not dot or skill_name not in skills:
            item.fail(f"{quote(key)} names no skill parameter: expected <Skill>.<parameter> with a skill of the library "
                      f"(skills: {listing(skills)})")
        declared = [p for p, _ in skills[skill_name].mapping(optional=("parameters",) + _SKILL_KEYS)["parameters"].items()]
        if name not in declared:
            item.fail(f"skill {skill_name} has no parameter {quote(name)} (parameters: {listing(declared)})")
        entry = item.mapping(optional=OVERRIDABLE)
        if not entry:
            item.fail(f"give at least one of {listing(OVERRIDABLE)}")
        out.setdefault(skill_name, {})[name] = item
    return out


_SKILL_KEYS = ("preconditions", "postconditions", "tree", "holdconditions")


def _skill_parameter(name: str, field: Field, types, override: Field | None = None) -> SkillParameter:
    f = field.mapping(optional=("type", "plan", "unit", "default", "bounds", "learnable", "description"))
    if "type" not in f:
        field.fail("missing key 'type'")
    if "default" not in f and "plan" not in f:
        field.fail("missing key 'default'")
    changed = override.mapping(optional=OVERRIDABLE) if override is not None else {}
    f.update(changed)  # the scenario's values win; their errors name the scenario's entry
    field = override if override is not None else field
    plan = f["plan"].boolean() if "plan" in f else False
    description = f["description"].string() if "description" in f else ""
    if plan:
        type_ = f["type"].string().lower()
        if type_ not in types:
            f["type"].fail(f"unknown type {quote(type_)} for a plan parameter (types: {listing(types)})")
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
        return SkillParameter(name, type_, False, unit, f["default"].vector(domain=PARAMETER), None, False, description)
    default = f["default"].number(PARAMETER)
    bounds = None
    if "bounds" in f:
        lower, upper = f["bounds"].vector(2, PARAMETER)
        if lower > upper:
            f["bounds"].fail(f"lower bound {lower} is above the upper bound {upper}")
        if not lower <= default <= upper:
            blamed = f["bounds"] if "bounds" in changed and "default" not in changed else f["default"]
            blamed.fail(f"default {default} is outside the bounds [{lower}, {upper}]")
        bounds = (lower, upper)
    if learnable:
        if bounds is None:
            field.fail("a learnable parameter needs bounds: [lower, upper]")
        if bounds[0] == bounds[1]:
            f["bounds"].fail(f"bounds [{bounds[0]:g}, {bounds[1]:g}] leave a learnable parameter nothing to learn; "
                             f"widen them or set learnable: false")
    return SkillParameter(name, type_, False, unit, default, bounds, learnable, description)


def manual_parameters(field: Field | None, skills) -> Mapping:
    """``manual_parameters``: set name -> ManualSet. Each value names a learnable parameter of a
    skill of the library as the plan names it ("<Skill>.<parameter>", "<Skill>#2.<parameter>"
    for a second use) and lies within that parameter's bounds. Whether a set fits a plan (names
    exactly the plan's learnable parameters) is checked when a goal is planned
    (``mjxskill.task``)."""
    if field is None:
        return frozen_mapping({})
    sets = {}
    for set_name, values_field in field.items():
        values = {}
        for key, item in values_field.items():
            parameter = _learnable_named(key, item, skills)
            v = item.number(PARAMETER)
            assert parameter.bounds is not None  # a learnable parameter has them (_skill_parameter)
            lower, upper = parameter.bounds
            if not lower <= v <= upper:
                item.fail(f"{v} is outside the bounds [{lower}, {upper}] {parameter.unit}")
            values[key] = v
        sets[set_name] = ManualSet(frozen_mapping(values), values_field.where())
    return frozen_mapping(sets)


def parameter_priors(field: Field | None, skills) -> Mapping:
    """``parameter_priors``: learnable parameter ("<Skill>[#k].<parameter>", as in
    ``manual_parameters``) -> ParameterPrior, ``{mean: m, std: s}`` in the parameter's unit: the
    mean inside the parameter's bounds, the std positive. The priors sit beside the scenario's
    task (the operator's knowledge of this task), not in the skill library the scenarios share."""
    if field is None:
        return frozen_mapping({})
    priors = {}
    for key, item in field.items():
        parameter = _learnable_named(key, item, skills)
        f = item.mapping(required=("mean", "std"))
        mean = f["mean"].number(PARAMETER)
        assert parameter.bounds is not None  # a learnable parameter has them (_skill_parameter)
        lower, upper = parameter.bounds
        if not lower <= mean <= upper:
            f["mean"].fail(f"prior mean {mean:g} is outside the bounds [{lower:g}, {upper:g}] {parameter.unit}")
        std = f["std"].number(PARAMETER)
        if not std > 0:
            f["std"].fail(f"prior std must be > 0 ({parameter.unit}), got {std:g}")
        if std < MIN_PRIOR_STD_SHARE * (upper - lower):
            f["std"].fail(f"prior std {std:g} {parameter.unit} is below {MIN_PRIOR_STD_SHARE:g} of the bounds' width "
                          f"{upper - lower:g}: a prior that narrow is a point the optimizer cannot evaluate its "
                          "density near")
        priors[key] = ParameterPrior(mean, std, item.where())
    return frozen_mapping(priors)


def _learnable_named(key: str, item: Field, skills) -> SkillParameter:
    """The learnable parameter ``key`` names; a located error at ``item`` listing the learnable
    ones when it names none."""
    parameter = _learnable(key, skills)
    if parameter is None:
        learnable = [f"{s.name}.{p.name}" for s in skills.values() for p in s.parameters if p.learnable]
        item.fail(f"{quote(key)} is not a learnable parameter of the skill library (learnable: {listing(learnable)})")
    return parameter


def _learnable(key: str, skills) -> SkillParameter | None:
    """The learnable parameter that ``"<Skill>[#k].<parameter>"`` names, or None."""
    label, dot, name = key.partition(".")
    skill_name, _, use = label.partition("#")
    if not dot or skill_name not in skills or (use and not (use.isdigit() and int(use) >= 2)):
        return None
    for p in skills[skill_name].parameters:
        if p.name == name and p.learnable:
            return p
    return None
