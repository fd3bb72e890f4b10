"""Plan -> eBT: every planned skill expands into its subtree of primitives; the plan is joined
under a SerialStar (``->*``), so a finished skill is not re-run.

Subtrees (after SkiREIL's skills; ``||FS`` = ParallelFs, ``->`` = Sequence):

* GoToLinear(target) = ``-> [ElementToBBPose(target approach pose), ||FS [MGSetGoalPose,
  EEPoseDistance(threshold)]]``.
* Push(workpiece, goal) = ``->* [||FS [GoToLinearOffset(workpiece + start offsets), ChangeStiffness],
  ||FS [GoToLinearOffset(goal + goal offsets), ChangeStiffness, ApplyForce(wrench)]]`` where
  GoToLinearOffset = GoToLinear with a learnable x/y offset, at the push height; the pusher is
  turned to the workpiece at the start and keeps its yaw on the way to the goal (a straight push).
* PegInsertion(peg, box) = ``-> [ElementToBBPose(box pose), ||FS [MGSetGoalPose,
  ChangeStiffness, ApplyForce(z = force), OverlayMotion(spiral), EEPoseDistance(threshold)]]``.

Leaves are primitives of ``mjxskill.ebt.primitives`` (its docstring says what each does).

Parameter names: ``"<Skill>.<parameter>"``, e.g. ``"Push.offset_x_start"``; the k-th use (k >= 2)
of a skill in one plan is ``"<Skill>#k.<parameter>"``. The learnable parameters are those of the
planned skills marked learnable in the world model, in plan order, then in the order the skill
declares them: that is the parameter-vector order everywhere else.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

from mjxskill.ebt.nodes import Node, action, parallel_fs, sequence, serial_star
from mjxskill.errors import PlanError

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario.schema import Scenario, WorldObject

@dataclass(frozen=True)
class PlanStep:
    """One planned skill. arguments: skill parameter -> scenario object name."""

    skill: str
    label: str  # "Push", or "Push#2" for the second Push of the plan
    arguments: Mapping[str, str]

    def __str__(self) -> str:
        return f"{self.skill}({', '.join(f'{k}={v}' for k, v in self.arguments.items())})"


@dataclass(frozen=True)
class LearnableParameter:
    name: str  # "Push.offset_x_start"
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
    steps, uses = [], {}
    for text in plan:
        tokens = text.strip().strip("()").split()
        if not tokens or tokens[0].lower() not in by_action:
            raise PlanError(f"plan step {text!r} names no skill of the library ({', '.join(scn.skills)})")
        skill = by_action[tokens[0].lower()]
        arguments = skill.arguments
        if len(tokens) - 1 != len(arguments):
            raise PlanError(f"plan step {text!r}: {skill.name} takes {len(arguments)} arguments")
        grounded = {}
        for parameter, name in zip(arguments, tokens[1:]):
            try:
                grounded[parameter.name] = scn.object_by_pddl_name(name).name
            except KeyError:
                raise PlanError(f"plan step {text!r}: unknown object {name!r}") from None
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
        expand, _ = EXPANSIONS[step.skill]
        subtrees.append(expand(_Context(scn, step)))
        skill = scn.skills[step.skill]
        for p in skill.parameters:
            if p.learnable:
                learnable.append(
                    LearnableParameter(
                        f"{step.label}.{p.name}", step.skill, p.name, p.unit,
                        float(p.bounds[0]), float(p.bounds[1]), float(p.default), p.description,
                    )
                )
    return serial_star("plan", *subtrees), tuple(learnable)


class _Context:
    """What an expansion reads: grounded objects and the skill's fixed parameter values."""

    def __init__(self, scn: "Scenario", step: PlanStep):
        self.scn, self.step = scn, step
        self.skill = scn.skills[step.skill]

    def object(self, argument: str) -> "WorldObject":
        name = self.step.arguments[argument]
        if name in self.scn.objects:
            return self.scn.objects[name]
        raise PlanError(f"{self.step}: {argument}={name} is not an object with a pose")

    def value(self, parameter: str):
        return self.skill.value(parameter)

    def inputs(self, **inputs: str) -> tuple[dict, dict]:
        """Leaf input -> skill parameter, split into (args with fixed values, params with the
        names of learnable ones)."""
        args, params = {}, {}
        for leaf_input, parameter in inputs.items():
            spec = self.skill.parameter(parameter)
            if spec.learnable:
                params[leaf_input] = f"{self.step.label}.{parameter}"
            else:
                args[leaf_input] = float(spec.default)
        return args, params


def _set_goal(obj: "WorldObject", offset, inputs=({}, {}), orientation: str = "tool_down_aligned") -> Node:
    args = {
        "object": obj.name,
        "mjcf_body": obj.mjcf_body,
        "offset": tuple(round(float(v), 9) for v in offset),  # no float noise in printed trees
        "orientation": orientation,
        **inputs[0],
    }
    return action("ElementToBBPose", "set_goal_from_object", args=args, params=inputs[1])


def _move(label: str, threshold: float) -> Node:
    return parallel_fs(
        f"{label}.move",
        action("MGSetGoalPose", "goal_pose"),
        action("EEPoseDistance", "ee_pose_distance", args={"threshold": float(threshold)}),
    )


def _stiffness(values) -> Node:
    return action("ChangeStiffness", "change_stiffness", args={"stiffness": tuple(float(v) for v in values)})


def expand_goto_linear(ctx: _Context) -> Node:
    target = ctx.object("target")
    return sequence(
        ctx.step.label,
        _set_goal(target, target.approach_offset),
        _move(ctx.step.label, ctx.value("threshold")),
    )


def expand_push(ctx: _Context) -> Node:
    label, height, threshold = ctx.step.label, ctx.value("push_height"), ctx.value("threshold")

    def goto_offset(obj: "WorldObject", which: str) -> Node:
        offset = (0.0, 0.0, height - float(obj.pose.position[2]))  # tool tip at the push height
        inputs = ctx.inputs(offset_x=f"offset_x_{which}", offset_y=f"offset_y_{which}")
        # The push starts with the pusher's faces turned to the workpiece's and goes straight
        # from there: turning the pusher on the way would twist the workpiece off the push line.
        orientation = "tool_down_aligned" if which == "start" else "tool_down"
        goal = _set_goal(obj, offset, inputs, orientation=orientation)
        return sequence(f"GoToLinearOffset.{which}", goal, _move(f"{label}.{which}", threshold))

    wrench = tuple(float(v) for v in ctx.value("wrench"))
    return serial_star(
        label,
        parallel_fs(f"{label}.start", goto_offset(ctx.object("workpiece"), "start"), _stiffness(ctx.value("stiffness"))),
        parallel_fs(
            f"{label}.goal",
            goto_offset(ctx.object("goal"), "goal"),
            _stiffness(ctx.value("stiffness")),
            action("ApplyForce", "apply_force", args={"wrench": wrench}),
        ),
    )


def expand_peg_insertion(ctx: _Context) -> Node:
    label, box = ctx.step.label, ctx.object("box")
    # SkiREIL's goal is the box's pose (its origin, under the hole): the reference keeps pulling
    # the peg down, and the distance check succeeds once the tip is within the threshold of it.
    force_args, force_params = ctx.inputs(force_z="force")
    spiral_args, spiral_params = ctx.inputs(radius="radius", path_velocity="path_velocity", pitch="pitch")
    return sequence(
        label,
        _set_goal(box, (0.0, 0.0, 0.0)),
        parallel_fs(
            f"{label}.insert",
            action("MGSetGoalPose", "goal_pose"),
            _stiffness(ctx.value("stiffness")),
            action("ApplyForce", "apply_force", args={"wrench": (0.0,) * 6, **force_args}, params=force_params),
            action("OverlayMotion", "overlay_spiral", args=spiral_args, params=spiral_params),
            action("EEPoseDistance", "ee_pose_distance", args={"threshold": float(ctx.value("threshold"))}),
        ),
    )


# skill name -> (expansion, parameters it reads: name -> "float" / "vector" / "float")
EXPANSIONS: Mapping[str, tuple[Callable[[_Context], Node], Mapping[str, str]]] = MappingProxyType(
    {
        "GoToLinear": (expand_goto_linear, {"threshold": "float"}),
        "Push": (
            expand_push,
            {
                "offset_x_start": "float",
                "offset_y_start": "float",
                "offset_x_goal": "float",
                "offset_y_goal": "float",
                "push_height": "float",
                "stiffness": "vector6",
                "wrench": "vector6",
                "threshold": "float",
            },
        ),
        "PegInsertion": (
            expand_peg_insertion,
            {
                "force": "float",
                "radius": "float",
                "path_velocity": "float",
                "pitch": "float",
                "stiffness": "vector6",
                "threshold": "float",
            },
        ),
    }
)
