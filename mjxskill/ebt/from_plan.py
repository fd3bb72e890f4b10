"""Plan -> eBT: every planned skill's tree (the template in its ``tree``, ``mjxskill.ebt.template``)
filled in with the plan's arguments and the skill's parameters; the plan is joined under a
SerialStar (``->*``), so a finished skill is not re-run. The skills and their trees are the world
model's (a YAML skill library); nothing here knows any skill.

Parameter names: ``"<Skill>.<parameter>"``; the k-th use (k >= 2) of a skill in one plan is
``"<Skill>#k.<parameter>"``. The learnable parameters are those of the planned skills marked
learnable in the world model, in plan order, then in the order the skill declares them: that is
the parameter-vector order everywhere else.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Mapping, Sequence

from mjxskill.ebt.nodes import Node, serial_star
from mjxskill.ebt.template import Binding, expand
from mjxskill.errors import PlanError, quote

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario.schema import Scenario

@dataclass(frozen=True)
class PlanStep:
    """One planned skill. arguments: skill parameter -> scenario object name."""

    skill: str
    label: str  # the skill's name, or "<name>#2" for its second use in the plan
    arguments: Mapping[str, str]

    def __str__(self) -> str:
        return f"{self.skill}({', '.join(f'{k}={v}' for k, v in self.arguments.items())})"


@dataclass(frozen=True)
class LearnableParameter:
    name: str  # "<label>.<parameter>"
    skill: str
    parameter: str
    unit: str
    lower: float
    upper: float
    default: float
    description: str = ""


def ground_plan(scn: "Scenario", plan: Sequence[str]) -> tuple[PlanStep, ...]:
    """Planner output ``["(gotolinear iiwa-1 home-1 peg-1)", ...]`` -> PlanSteps."""
    by_action = {skill.pddl_name: skill for skill in scn.skills.values()}
    steps: list[PlanStep] = []
    uses: dict[str, int] = {}
    for text in plan:
        tokens = text.strip().strip("()").split()
        if not tokens or tokens[0].lower() not in by_action:
            raise PlanError(f"plan step {quote(text)} names no skill of the library ({', '.join(scn.skills)})")
        skill = by_action[tokens[0].lower()]
        arguments = skill.arguments
        if len(tokens) - 1 != len(arguments):
            raise PlanError(f"plan step {quote(text)}: {skill.name} takes {len(arguments)} arguments")
        grounded = {}
        for parameter, name in zip(arguments, tokens[1:]):
            try:
                grounded[parameter.name] = scn.object_by_pddl_name(name).name
            except KeyError:
                raise PlanError(f"plan step {quote(text)}: unknown object {quote(name)}") from None
        uses[skill.name] = uses.get(skill.name, 0) + 1
        label = skill.name if uses[skill.name] == 1 else f"{skill.name}#{uses[skill.name]}"
        steps.append(PlanStep(skill.name, label, MappingProxyType(grounded)))
    return tuple(steps)


def plan_to_tree(scn: "Scenario", steps: Sequence[PlanStep]) -> tuple[Node, tuple[LearnableParameter, ...]]:
    """The eBT of the plan and its learnable parameters (in parameter-vector order)."""
    if not steps:
        raise PlanError("the plan is empty: the goal already holds in the initial state")
    subtrees, learnable = [], []
    for step in steps:
        skill = scn.skills[step.skill]
        subtrees.append(expand(skill.tree, _binding(scn, step)))
        for p in skill.parameters:
            if p.learnable:
                # a float with bounds (mjxskill.scenario.skills._skill_parameter)
                assert p.bounds is not None and isinstance(p.default, float)
                learnable.append(
                    LearnableParameter(
                        f"{step.label}.{p.name}", step.skill, p.name, p.unit,
                        float(p.bounds[0]), float(p.bounds[1]), float(p.default), p.description,
                    )
                )
    return serial_star("plan", *subtrees), tuple(learnable)


def _binding(scn: "Scenario", step: PlanStep) -> Binding:
    """What the skill's template reads for ``step``: its parameters and the plan's objects."""
    skill = scn.skills[step.skill]

    def obj(argument: str):
        name = step.arguments[argument]
        if name in scn.objects:
            return scn.objects[name]
        raise PlanError(f"{step}: {argument}={name} is not an object with a pose")

    def fixed(parameter: str):
        value = skill.value(parameter)
        return tuple(float(v) for v in value) if isinstance(value, tuple) else float(value)

    return Binding(step.label, lambda p: skill.parameter(p).learnable, fixed, obj)
