"""Scenario files: the numbers of the paper/reference, immutability, and one clear error (file,
key path, line) for every kind of invalid file."""

import copy
import dataclasses
import functools
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from mjxskill.scenario import SCENARIO_DIR, ScenarioError, load_scenario
from mjxskill.task import plan_task
from scenario_texts import library_text, shipped_text, write_library_copy

PUSH_YAML = SCENARIO_DIR / "push.yaml"
PUSH_TEXT = shipped_text("push")  # the scene path absolute: edited copies load from tmp_path


def test_push_world_model_has_the_papers_numbers(push):
    assert push.name == "push" and push.source == str(PUSH_YAML)
    assert Path(push.scene) == (SCENARIO_DIR.parent / "push.xml").resolve()
    assert (push.episode_seconds, push.bt_hz, push.control_hz) == (12.0, 10, 500)
    assert push.episode_ticks == 120 and push.steps_per_tick == 50
    obj, goal = push.objects["ObjectToBePushed-1"], push.objects["ObjectGoalPose-1"]
    assert obj.mjcf_body == "object" and obj.mass == 2.5
    np.testing.assert_allclose(obj.size, [0.15, 0.30, 0.07])
    assert 0.2 <= obj.friction <= 0.25 and np.linalg.norm(obj.com_offset) > 0
    distance = np.linalg.norm(goal.pose.position[:2] - obj.pose.position[:2])
    assert distance == pytest.approx(0.43, abs=1e-3)
    assert goal.pose.rpy_deg[2] - obj.pose.rpy_deg[2] == pytest.approx(26.0)
    assert push.objects["Pusher-1"].size.tolist() == [0.07, 0.07, 0.05]
    assert push.robot.start_configs.shape == (4, 7) and push.robot.eval_configs.shape == (2, 7)
    assert push.robot.tool_site == "tool" and push.robot.nullspace_stiffness == 5.0
    np.testing.assert_allclose(push.robot.default_stiffness, [400, 400, 400, 50, 50, 50])
    np.testing.assert_allclose(push.robot.home, [0, 0.785, 0, -1.571, 0, 0, 0])
    assert push.success.kind == "object_at_pose"
    assert (push.success.position_tolerance, push.success.orientation_tolerance_deg) == (0.01, 5.0)
    # the paper: object and goal offsets Gaussian with sd 7 mm, not clipped
    assert push.randomization.n_worlds == 7 and dict(push.randomization.xy_sigma) == {
        "ObjectToBePushed-1": 0.007,
        "ObjectGoalPose-1": 0.007,
    }
    assert push.randomization.clip_sigmas is None
    assert push.optimizer.budget == 400 and push.optimizer.repetitions == 10
    assert push.objective_names == ("success", "applied_force")
    assert {r.objective for r in push.rewards} == set(push.objective_names)


def test_peg_world_model_has_the_papers_numbers(peg):
    assert (peg.episode_seconds, peg.gravity) == (18.0, False)
    box, item = peg.objects["BoxWithHole-1"], peg.objects["Peg-1"]
    assert box.mjcf_body == "box" and item.mjcf_body == "tool_tool"
    # a round peg in a round hole of a 1.5 mm larger radius
    assert item.shape == "cylinder" and item.size.tolist() == [0.015, 0.05]  # radius, length
    assert box.shape == "box_with_round_hole"
    assert box.extra["hole_clearance"] == 0.0015 and box.extra["hole_depth"] > 0.01
    # the box's offsets Gaussian with sd 7 mm, not clipped
    assert dict(peg.randomization.xy_sigma) == {"BoxWithHole-1": 0.007} and peg.randomization.clip_sigmas is None
    assert box.friction == 0.3
    assert peg.robot.start_configs.shape == (5, 7) and peg.robot.eval_configs.shape == (10, 7)
    assert peg.success.kind == "inserted" and peg.success.depth == 0.01
    rewards = {r.name: r for r in peg.rewards}
    assert rewards["bt_success"].constants["value"] == 8.0
    assert dict(rewards["peg_to_box"].constants) == {"w": 2.0, "d_o": 0.006}
    assert rewards["peg_to_box"].weight == 0.15
    assert rewards["applied_wrench"].weight < 0  # a cost on a maximized objective


def test_learnable_parameters_come_from_the_plan(push, peg):
    assert plan_task(push).parameter_names == (
        "Push.offset_x_start", "Push.offset_y_start", "Push.offset_x_goal", "Push.offset_y_goal",
    )
    np.testing.assert_array_equal(plan_task(push).bounds, [[-0.3] * 4, [0.3] * 4])
    assert plan_task(push).parameter_units == ("m",) * 4
    np.testing.assert_array_equal(plan_task(push).defaults, np.zeros(4))
    # the paper's three: downward force, spiral radius and path velocity; the pitch a constant
    assert plan_task(peg).parameter_names == ("PegInsertion.force", "PegInsertion.radius", "PegInsertion.path_velocity")
    np.testing.assert_array_equal(plan_task(peg).bounds, [[-10, 0, 0], [0, 0.07, 0.3]])
    assert plan_task(peg).parameter_units == ("N", "m", "m/s")
    assert plan_task(peg).defaults[1:].tolist() == [0, 0]  # no search motion
    pitch = peg.skills["PegInsertion"].parameter("pitch")
    assert not pitch.learnable and pitch.default == 0.0015  # peg.yaml's, over the library's 2 mm
    # tighter than the diametral clearance: the reference's turns lie a pitch apart and the peg
    # drops in within the clearance of the hole's axis, and the trailing tool's turns lie wider
    assert pitch.default < 2 * peg.objects["BoxWithHole-1"].extra["hole_clearance"]
    for scn in (push, peg, load_scenario("peg_square")):
        assert len(scn.manual_parameters) >= 3
        task = plan_task(scn)
        assert set(task.manual_parameters) == set(scn.manual_parameters)  # every set fits the plan
        for values in task.manual_parameters.values():
            assert values.shape == (len(task.parameter_names),)
            assert np.all(task.bounds[0] <= values) and np.all(values <= task.bounds[1])


def test_the_square_peg_variant_is_the_same_task_with_square_geometry(peg):
    square = load_scenario("peg_square")
    assert square.objects["Peg-1"].shape == "box" and square.objects["BoxWithHole-1"].shape == "box_with_hole"
    assert square.objects["Peg-1"].size.tolist() == [0.03, 0.03, 0.05]
    assert square.objects["BoxWithHole-1"].extra["hole_clearance"] == 0.0015
    assert plan_task(square).parameter_names == plan_task(peg).parameter_names
    assert dict(square.randomization.xy_sigma) == dict(peg.randomization.xy_sigma)
    assert square.randomization.clip_sigmas is None


def _peg_text_with_library_pitch() -> str:
    """peg.yaml without its own pitch entry, so that a test's entry is the only one (the
    library's default, 2 mm, stands)."""
    text = shipped_text("peg")
    assert text.count("  PegInsertion.pitch: {default: 0.0015}\n") == 1
    return text.replace("  PegInsertion.pitch: {default: 0.0015}\n", "")


def test_a_scenario_makes_a_library_constant_learnable(tmp_path):
    # the pitch, a constant of the skill library, learnable with the scenario's bounds, and the
    # operators' sets then name it
    text = _peg_text_with_library_pitch().replace(
        "skill_parameters:\n", "skill_parameters:\n  PegInsertion.pitch: {learnable: true, bounds: [0.0, 0.003]}\n")
    text = re.sub(r"(operator_\w: \{[^}]*)\}", r"\1, PegInsertion.pitch: 0.002}", text)
    path = tmp_path / "peg.yaml"
    path.write_text(text)
    task = plan_task(load_scenario(path))
    assert task.parameter_names[-1] == "PegInsertion.pitch"
    np.testing.assert_array_equal(task.bounds[:, -1], [0.0, 0.003])
    assert task.defaults[-1] == 0.002
    assert load_scenario("peg").skills["PegInsertion"].parameter("pitch").learnable is False  # the library unchanged


@pytest.mark.parametrize("entry, key, message", [
    ("PegInsertion.pitch: {learnable: true, bounds: [0.003, 0.01]}", "skill_parameters.PegInsertion.pitch.bounds",
     "default 0.002 is outside the bounds"),
    ("PegInsertion.pitchh: {learnable: true}", "skill_parameters.PegInsertion.pitchh", "has no parameter 'pitchh'"),
    ("PegInsert.pitch: {learnable: true}", "skill_parameters.PegInsert.pitch", "names no skill parameter"),
    ("PegInsertion.pitch: {learnable: true, bounds: [0.002, 0.002]}", "skill_parameters.PegInsertion.pitch.bounds",
     "nothing to learn"),
    ("PegInsertion.pitch: {}", "skill_parameters.PegInsertion.pitch", "give at least one of"),
    ("PegInsertion.pitch: {unit: mm}", "skill_parameters.PegInsertion.pitch.unit", "unknown key .unit."),
    ("PegInsertion.box: {learnable: true}", "skill_parameters.PegInsertion.box.learnable", "a plan parameter"),
    ("PegInsertion.stiffness: {learnable: true}", "skill_parameters.PegInsertion.stiffness", "vector parameters cannot be learnable"),
])
def test_a_bad_skill_parameter_entry_is_an_error_naming_it(tmp_path, entry, key, message):
    text = _peg_text_with_library_pitch().replace("skill_parameters:\n", f"skill_parameters:\n  {entry}\n")
    path = tmp_path / "peg.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=rf"peg.yaml: {re.escape(key)} \(line \d+\): .*{message}") as err:
        load_scenario(path)
    assert "as included by" not in str(err.value)


def test_start_configurations_respect_the_iiwa_joint_limits(push, peg):
    limits = np.deg2rad([170, 120, 170, 120, 170, 120, 175])
    for scn in (push, peg):
        configs = np.concatenate([scn.robot.start_configs, scn.robot.eval_configs])
        assert np.all(np.abs(configs) < limits)
        assert len(np.unique(configs.round(3), axis=0)) == len(configs)  # all different


def test_pose_quaternion_matches_the_closed_form(push):
    # yaw only: q = (cos(yaw/2), 0, 0, sin(yaw/2))
    quat = push.objects["ObjectGoalPose-1"].pose.quat
    half = math.radians(26) / 2
    np.testing.assert_allclose(quat, [math.cos(half), 0, 0, math.sin(half)], atol=1e-12)
    # roll 180 deg (tool pointing down): q = (0, 1, 0, 0)
    np.testing.assert_allclose(push.objects["Home-1"].pose.quat, [0, 1, 0, 0], atol=1e-12)


def test_scenario_is_immutable(push):
    with pytest.raises(dataclasses.FrozenInstanceError):
        push.goal = "(at a b)"
    with pytest.raises(TypeError):
        push.objects["new"] = push.objects["Home-1"]
    with pytest.raises(ValueError):
        push.robot.start_configs[0, 0] = 1.0
    with pytest.raises(ValueError):
        plan_task(push).bounds[0, 0] = 1.0
    with pytest.raises(TypeError):
        push.skills["Push"].parameters[0] = None


def test_scenario_is_hashable_for_use_as_a_static_jit_argument(push):
    assert hash(push) == hash(push) and push == push
    assert {push: 1}[push] == 1


def test_load_by_path_equals_load_by_name(push):
    again = load_scenario(PUSH_YAML)
    assert plan_task(again).parameter_names == plan_task(push).parameter_names and again.source == push.source


def test_unknown_task_name_lists_the_available_ones():
    with pytest.raises(ScenarioError, match=r"unknown task 'pusj'.*available: peg, peg_square, push"):
        load_scenario("pusj")


# -- invalid files ------------------------------------------------------------------------------
# (old text, new text, key path, message[, line anchor]) applied to push.yaml; the error must
# name the file, the key path and the line of the last occurrence of the anchor (default: the
# new text) in the edited file.
MUTATIONS = {
    "missing key": ("episode_seconds: 12.0\n", "", "<top level>", "missing key 'episode_seconds'"),
    "unknown key": (
        "    com_offset: [-0.02", "    bogus: 1\n    com_offset: [-0.02",
        "objects.ObjectToBePushed-1.bogus", "unknown key 'bogus'", "bogus: 1",
    ),
    "wrong type": ("    mass: 2.5", "    mass: heavy", "objects.ObjectToBePushed-1.mass", "expected a number, got 'heavy'"),
    "wrong type in a list": (
        "- [-0.1200, 0.7679,", "- [-0.1200, x,", r"robot.start_configs\[0\]\[1\]", "expected a number, got 'x'",
    ),
    "wrong vector length": (
        "default_stiffness: [400, 400, 400, 50, 50, 50]", "default_stiffness: [400, 400]",
        "robot.default_stiffness", "expected a list of 6 numbers, got 2",
    ),
    "unknown object in randomization": (
        "xy_sigma: {ObjectToBePushed-1: 0.007,", "xy_sigma: {ObjectToBePushed-2: 0.007,",
        "randomization.xy_sigma.ObjectToBePushed-2", "unknown object 'ObjectToBePushed-2'",
    ),
    "unknown object in a relation": (
        "    - (can-push iiwa-1)", "    - (can-push iiwa-2)", r"robot.relations\[1\]", "unknown object 'iiwa-2'.*did you mean iiwa-1",
    ),
    "wrong arity": (
        "      - (pushable ObjectToBePushed-1)", "      - (pushable ObjectToBePushed-1 Home-1)",
        r"objects.ObjectToBePushed-1.relations\[0\]", "takes 1 arguments",
    ),
    "wrong argument type": (
        "      - (pushable ObjectToBePushed-1)", "      - (pushable Home-1)",
        r"objects.ObjectToBePushed-1.relations\[0\]", "'home-1' is a pose",
    ),
    "unknown type": ("    type: item\n    mjcf_body: object", "    type: thing\n    mjcf_body: object",
                     "objects.ObjectToBePushed-1.type", "unknown type 'thing'"),
    "duplicate object name": ("  Home-1:\n", "  ObjectGoalPose-1:\n", "objects.ObjectGoalPose-1", "duplicate key 'ObjectGoalPose-1'",
                              "ObjectGoalPose-1:\n    type: pose\n    shape: pose"),
    "names differing only in case": ("  Home-1:\n", "  objectgoalpose-1:\n", "objects.objectgoalpose-1", "duplicate name 'objectgoalpose-1'"),
    "duplicate reward name": ("  - {name: object_orientation,", "  - {name: object_position,", r"rewards\[1\].name", "duplicate reward name"),
    # names become PDDL symbols, CSV headers and file-name parts: one rule, bounded, ASCII
    "scenario name too long": ("name: push\n", "name: " + "p" * 101 + "\n", "name", "at most 100 characters"),
    "scenario name not ASCII": ("name: push\n", "name: pushé\n", "name", "'pushé' is not usable as a scenario name"),
    "scenario name not starting with a letter": ("name: push\n", "name: 1push\n", "name", "'1push' is not usable"),
    "object key too long": (
        "  ObjectToBePushed-1:\n", "  " + "O" * 150 + ":\n", "objects", "a key of 150 characters",
    ),
    "text too long": (
        "goal: (skiros:at", "goal: " + "(" * 10_001 + " (skiros:at", "goal", "a text of 10063 characters.*at most 10000",
    ),
    "unknown objective": ("{name: ee_to_goal, kind: exp_ee_to_goal, objective: success,",
                          "{name: ee_to_goal, kind: exp_ee_to_goal, objective: sucess,",
                          r"rewards\[2\].objective", "unknown objective 'sucess'"),
    "unknown reward kind": ("kind: exp_ee_to_reference", "kind: exp_ee_to_ref", r"rewards\[3\].kind", "'exp_ee_to_ref' is not one of"),
    "joint angle outside its limit": ("- [-0.1200, 0.7679,", "- [-0.1200, 2.7679,", r"robot.start_configs\[0\]\[1\]", "outside the joint limit"),
    "n_init above budget": ("  n_init: 48", "  n_init: 480", "optimizer.n_init", "exceeds the budget 400"),
    # The pick's force bound: a number >= 0 with its reason.
    "pick bound negative": ("  max_force: 10.0\n", "  max_force: -3\n", "pick.max_force", "expected a number >= 0, got -3"),
    "pick bound not a number": ("  max_force: 10.0\n", "  max_force: lots\n", "pick.max_force", "expected a number, got 'lots'"),
    "manual parameter not learnable": ("operator_a: {Push.offset_x_start: -0.03,", "operator_a: {Push.offset_z_start: -0.03,",
                                       "manual_parameters.operator_a.Push.offset_z_start", "not a learnable parameter"),
    "manual parameter outside bounds": ("operator_b: {Push.offset_x_start: -0.04,", "operator_b: {Push.offset_x_start: 0.5,",
                                        "manual_parameters.operator_b.Push.offset_x_start", "outside the bounds"),
    # An operator's prior on a learnable parameter (parameter_priors, beside manual_parameters).
    "prior mean outside bounds": ("manual_parameters:\n", "parameter_priors:\n  Push.offset_x_start: {mean: 0.5, std: 0.05}\nmanual_parameters:\n",
                                  "parameter_priors.Push.offset_x_start.mean", r"prior mean 0.5 is outside the bounds \[-0.3, 0.3\] m",
                                  "Push.offset_x_start: {mean: 0.5"),
    "prior std not positive": ("manual_parameters:\n", "parameter_priors:\n  Push.offset_y_goal:\n    mean: -0.1\n    std: 0\nmanual_parameters:\n",
                               "parameter_priors.Push.offset_y_goal.std", r"prior std must be > 0 \(m\), got 0", "std: 0"),
    "prior of no learnable parameter": ("manual_parameters:\n", "parameter_priors:\n  Push.push_height: {mean: 0.02, std: 0.01}\nmanual_parameters:\n",
                                        "parameter_priors.Push.push_height", "not a learnable parameter", "Push.push_height"),
    "prior without std": ("manual_parameters:\n", "parameter_priors:\n  Push.offset_y_goal: {mean: -0.1}\nmanual_parameters:\n",
                          "parameter_priors.Push.offset_y_goal", "missing key 'std'", "Push.offset_y_goal: {mean: -0.1}"),
    "goal with an unknown object": ("goal: (skiros:at skiros:ObjectToBePushed-1 skiros:ObjectGoalPose-1)",
                                    "goal: (skiros:at skiros:ObjectToBePushed-1 skiros:ObjectGoalPose-2)",
                                    "goal", "unknown object 'objectgoalpose-2'.*did you mean objectgoalpose-1"),
    "goal no plan reaches": ("    - (can-push iiwa-1)\n", "", "goal", "no plan reaches the goal", "goal: (skiros:at"),
    "goal not balanced": ("goal: (skiros:at skiros:ObjectToBePushed-1 skiros:ObjectGoalPose-1)",
                          "goal: (skiros:at skiros:ObjectToBePushed-1 skiros:ObjectGoalPose-1",
                          "goal", "unbalanced parentheses"),
}

# The same for the shipped skill library (assets/skills/library.yaml), included by a push.yaml
# copy: the error names the library file. Bad templates: an unknown kind, primitive or input, a
# reference to no parameter, a value of the wrong kind, a learnable parameter where the leaf
# fixes its value or that no leaf reads, an input missing.
LIBRARY_MUTATIONS = {
    "lower bound above upper": (
        "offset_x_start: {type: float, unit: m, default: 0.0, bounds: [-0.3, 0.3]",
        "offset_x_start: {type: float, unit: m, default: 0.0, bounds: [0.4, 0.3]",
        "skills.Push.parameters.offset_x_start.bounds", "lower bound 0.4 is above the upper bound 0.3",
    ),
    "default outside bounds": (
        "force: {type: float, unit: N, default: -5.0,", "force: {type: float, unit: N, default: 5.0,",
        "skills.PegInsertion.parameters.force.default", r"default 5.0 is outside the bounds \[-10.0, 0.0\]",
    ),
    "learnable without bounds": (
        "offset_y_goal: {type: float, unit: m, default: 0.0, bounds: [-0.3, 0.3], learnable: true}",
        "offset_y_goal: {type: float, unit: m, default: 0.0, learnable: true}",
        "skills.Push.parameters.offset_y_goal", "a learnable parameter needs bounds",
    ),
    "unknown predicate in a condition": (
        'holdconditions: ["(can-push ?robot)"]', 'holdconditions: ["(can-pusher ?robot)"]',
        r"skills.Push.holdconditions\[0\]", "unknown predicate 'can-pusher'; did you mean can-push",
    ),
    "unknown variable in a condition": (
        'postconditions: ["(at ?peg ?box)"]', 'postconditions: ["(at ?peg ?hole)"]',
        r"skills.PegInsertion.postconditions\[0\]", r"unknown parameter '\?hole'",
    ),
    "unknown processor": ("    tree:\n      sequence: $label\n      children:\n        - action: ElementToBBPose\n          primitive: set_goal_from_object\n          args: {object: $target",
                          "    tree:\n      sequnce: $label\n      children:\n        - action: ElementToBBPose\n          primitive: set_goal_from_object\n          args: {object: $target",
                          "skills.GoToLinear.tree", "exactly one of sequence, serial_star", "tree:\n      sequnce"),
    "unknown primitive": ("    - {action: MGSetGoalPose, primitive: goal_pose}\n            - {action: ChangeStiffness",
                          "    - {action: MGSetGoalPose, primitive: goal_poses}\n            - {action: ChangeStiffness",
                          r"skills.PegInsertion.tree.children\[1\].children\[0\].primitive", "unknown primitive 'goal_poses'"),
    "unknown input": ("args: {radius: $radius, path_velocity: $path_velocity, pitch: $pitch}",
                      "args: {radius: $radius, path_speed: $path_velocity, pitch: $pitch}",
                      r"skills.PegInsertion.tree.children\[1\].children\[3\].args.path_speed", "overlay_spiral has no input 'path_speed'"),
    "unknown parameter": ("force_z: $force}", "force_z: $forse}",
                          r"skills.PegInsertion.tree.children\[1\].children\[2\].args.force_z", r"\$forse names no parameter"),
    "wrong argument": ("args: {stiffness: $stiffness}}\n            - {action: ApplyForce, primitive: apply_force, args: {wrench: [0",
                       "args: {stiffness: $threshold}}\n            - {action: ApplyForce, primitive: apply_force, args: {wrench: [0",
                       r"skills.PegInsertion.tree.children\[1\].children\[1\].args.stiffness", r"\$threshold is a number; expected 6 values"),
    "learnable read by no leaf": ("force_z: $force}", "force_z: -5.0}", r"skills.PegInsertion.tree", "'force' is not read by the tree",
                                  "    tree:\n      sequence: $label\n      children:\n        - action: ElementToBBPose\n          primitive: set_goal_from_object\n          args: {object: $box"),
    "learnable in a fixed input": ("$label.start.move\n                  children:\n                    - {action: MGSetGoalPose, primitive: goal_pose}\n                    - {action: EEPoseDistance, primitive: ee_pose_distance, args: {threshold: $threshold}}",
                                   "$label.start.move\n                  children:\n                    - {action: MGSetGoalPose, primitive: goal_pose}\n                    - {action: EEPoseDistance, primitive: ee_pose_distance, args: {threshold: $offset_x_goal}}",
                                   r"skills.Push.tree.children\[0\].children\[0\].children\[1\].children\[1\].args.threshold",
                                   "offset_x_goal is learnable: this input is fixed when the tree is built", "threshold: $offset_x_goal"),
    "input missing": ("{action: ChangeStiffness, primitive: change_stiffness, args: {stiffness: $stiffness}}\n        - parallel_fs: $label.goal",
                      "{action: ChangeStiffness, primitive: change_stiffness}\n        - parallel_fs: $label.goal",
                      r"skills.Push.tree.children\[0\].children\[1\]", "change_stiffness needs the input 'stiffness'",
                      "{action: ChangeStiffness, primitive: change_stiffness}"),
    "not a plan argument": ("args: {object: $box, offset: [0, 0, 0]", "args: {object: $force, offset: [0, 0, 0]",
                            r"skills.PegInsertion.tree.children\[0\].args.object", "expected a plan argument naming an object"),
    "attribute of a number": ("offset: [0, 0, $push_height - $workpiece.position.z]", "offset: [0, 0, $push_height - $threshold.position.z]",
                              r"skills.Push.tree.children\[0\].children\[0\].children\[0\].args.offset\[2\]",
                              "only a plan argument .an object. has attributes"),
}


def assert_located(error: str, file, key_path: str, message: str, mutated: str, anchor: str) -> None:
    """``error`` is one line naming ``file``, ``key_path`` and the line of the last ``anchor`` in
    ``mutated`` (no anchor: the document's first line), and says ``message``."""
    assert error.startswith(f"{file}: ") and "\n" not in error, error
    assert re.search(rf": {key_path} \(line (\d+)\): ", error), error
    assert re.search(message, error), error
    line = int(re.search(r"\(line (\d+)\)", error).group(1))
    if anchor:
        assert line == mutated[: mutated.rindex(anchor)].count("\n") + 1, error
    else:  # a missing top-level key is reported at the document's start
        assert line == 1 + next(i for i, l in enumerate(mutated.splitlines()) if l and not l.startswith("#")), error


def test_the_pick_bound_is_the_scenarios_number_with_its_reason(push, peg):
    # 10 N: PegInsertion.force's bound (the most a learned set may command); push's constant
    # 7 N press lies within it
    for scn in (push, peg):
        assert scn.pick.max_force == 10.0 and "10 N" in scn.pick.why and "\n" not in scn.pick.why


@pytest.mark.parametrize("block, key_path, message", [
    ("pick:\n  max_force: 5.0\n", "pick", "missing key 'why'"),
    ("pick:\n  max_force: 5.0\n  why: ''\n", "pick.why", "expected the reason for the bound"),
    ("pick:\n  max_force: 5.0\n  why: [a]\n", "pick.why", "expected a single value"),
    ("pick:\n  why: gentle\n", "pick", "missing key 'max_force'"),
    ("pick:\n  max_force: .inf\n  why: gentle\n", "pick.max_force", "expected a finite number"),
])
def test_a_bad_pick_bound_is_an_error_naming_it(tmp_path, block, key_path, message):
    start = PUSH_TEXT.index("pick:\n")
    end = PUSH_TEXT.index("\n\n", start) + 1
    mutated = PUSH_TEXT[:start] + block + PUSH_TEXT[end:]
    path = tmp_path / "push.yaml"
    path.write_text(mutated)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert_located(str(info.value), path, key_path, message, mutated, key_path.split(".")[-1] + ":")


def test_a_scenario_without_a_pick_bound_states_none(tmp_path):
    start = PUSH_TEXT.index("pick:\n")
    path = tmp_path / "push.yaml"
    path.write_text(PUSH_TEXT[:start] + PUSH_TEXT[PUSH_TEXT.index("\n\n", start) + 2:])
    assert load_scenario(path).pick is None


@pytest.mark.parametrize("kind", list(MUTATIONS))
def test_invalid_file_fails_naming_file_key_and_line(kind, tmp_path):
    old, new, key_path, message, *anchor = MUTATIONS[kind]
    assert PUSH_TEXT.count(old) == 1, f"mutation anchor for {kind!r} must occur once"
    mutated = PUSH_TEXT.replace(old, new)
    path = tmp_path / "push.yaml"
    path.write_text(mutated)
    with pytest.raises(ScenarioError) as info:
        plan_task(load_scenario(path))  # most fail to load; a goal no plan reaches fails to plan
    assert_located(str(info.value), path, key_path, message, mutated, anchor[0] if anchor else new.strip())


@pytest.mark.parametrize("kind", list(LIBRARY_MUTATIONS))
def test_an_invalid_skill_library_fails_naming_its_file_key_and_line(kind, tmp_path):
    old, new, key_path, message, *anchor = LIBRARY_MUTATIONS[kind]
    text = library_text()
    assert text.count(old) == 1, f"mutation anchor for {kind!r} must occur once"
    mutated = text.replace(old, new)
    path = write_library_copy(tmp_path, "push", mutated)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert_located(str(info.value), tmp_path / "library.yaml", key_path, message, mutated, anchor[0] if anchor else new.strip())


def test_a_skill_in_the_scenario_and_in_its_library_is_named_twice(tmp_path):
    extra = "skills:\n  GoToLinear:\n    parameters: {}\n    preconditions: []\n    postconditions: []\n    tree: {}\n"
    path = write_library_copy(tmp_path, "push", library_text())
    path.write_text(path.read_text() + extra)
    with pytest.raises(ScenarioError, match=r"skills.GoToLinear \(line \d+\): skill 'GoToLinear' is defined twice; "
                                            r"the first is at .*library.yaml: skills.GoToLinear \(line \d+\)"):
        load_scenario(path)


def test_not_yaml_at_all(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("name: push\nrobot: [1, 2\n")
    with pytest.raises(ScenarioError, match=rf"^{re.escape(str(path))} \(line \d+, column \d+\): not valid YAML"):
        load_scenario(path)


def test_empty_and_missing_files(tmp_path):
    (tmp_path / "empty.yaml").write_text("")
    with pytest.raises(ScenarioError, match="the file is empty"):
        load_scenario(tmp_path / "empty.yaml")
    with pytest.raises(ScenarioError, match="cannot read the scenario file"):
        load_scenario(tmp_path / "missing.yaml")


def test_yaml_tags_are_not_executed(tmp_path):
    path = tmp_path / "evil.yaml"
    path.write_text(PUSH_YAML.read_text().replace("name: push", "name: !!python/object/apply:os.system ['echo hi']"))
    with pytest.raises(ScenarioError, match="name"):
        load_scenario(path)


def _paths(tree, prefix=()):
    """Every key path of a loaded YAML tree (mappings and lists)."""
    items = tree.items() if isinstance(tree, dict) else enumerate(tree) if isinstance(tree, list) else ()
    for key, value in items:
        yield (*prefix, key)
        yield from _paths(value, (*prefix, key))


PUSH_TREE = yaml.safe_load(PUSH_TEXT)
PUSH_PATHS = list(_paths(PUSH_TREE))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    path=st.sampled_from(PUSH_PATHS),
    edit=st.sampled_from(["delete", "text", "number", "list", "mapping", "null", "negative"]),
)
@example(path=("predicates", "at"), edit="delete")  # an error the included skill library reports
def test_any_edit_loads_or_fails_with_a_located_scenario_error(tmp_path, path, edit):
    tree = copy.deepcopy(PUSH_TREE)
    parent = functools.reduce(lambda node, key: node[key], path[:-1], tree)
    replacement = {"text": "zzz", "number": 3, "list": [1, 2], "mapping": {"a": 1}, "null": None, "negative": -1.0}
    if edit == "delete":
        del parent[path[-1]]
    else:
        parent[path[-1]] = replacement[edit]
    target = tmp_path / f"edited-{abs(hash((path, edit)))}.yaml"
    target.write_text(yaml.safe_dump(tree, sort_keys=False))
    try:
        load_scenario(target)
    except ScenarioError as err:  # the only exception a bad file may raise
        # located in the edited file, or in the skill library it includes where the edit broke a
        # name the library uses (deleting predicates.at: the library's Push still says 'at')
        located = str(err).startswith(f"{target}: ") or f"(as included by {target}," in str(err)
        assert located and "(line " in str(err) and "\n" not in str(err), str(err)
