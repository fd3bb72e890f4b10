"""Plan -> eBT: the skills' subtrees as SkiREIL builds them, leaves from the documented
vocabulary, learnable parameters wired to leaves, and the trees run by the reference
interpreter against a scripted world."""

import dataclasses
from types import MappingProxyType

import pytest

from mjxskill.ebt.from_plan import ground_plan, plan_to_tree
from mjxskill.ebt.primitives import PRIMITIVES
from mjxskill.errors import PlanError
from mjxskill.ebt.interpreter import Interpreter
from mjxskill.ebt.nodes import SYMBOLS, Node, Status
from mjxskill.task import plan_task


def shape(node: Node):
    """(symbol, name) for processors, the primitive for leaves, nested like the tree."""
    if node.is_leaf:
        return node.primitive
    return (SYMBOLS[node.kind], node.name, *(shape(c) for c in node.children))


GOTO = ("->", "GoToLinear", "set_goal_from_object", ("||FS", "GoToLinear.move", "goal_pose", "ee_pose_distance"))


def test_push_tree_is_gotolinear_then_serial_star_of_two_parallel_fs_blocks(push):
    def offset_move(which):
        return ("->", f"GoToLinearOffset.{which}", "set_goal_from_object",
                ("||FS", f"Push.{which}.move", "goal_pose", "ee_pose_distance"))

    assert shape(plan_task(push).tree) == (
        "->*", "plan",
        GOTO,
        ("->*", "Push",
         ("||FS", "Push.start", offset_move("start"), "change_stiffness"),
         ("||FS", "Push.goal", offset_move("goal"), "change_stiffness", "apply_force")),
    )
    leaves = {(n.name, n.args.get("object")): n for n in plan_task(push).tree.leaves() if n.primitive == "change_stiffness"}
    for leaf in leaves.values():
        assert leaf.args["stiffness"] == (700, 700, 700, 50, 50, 50)
    force = next(n for n in plan_task(push).tree.leaves() if n.primitive == "apply_force")
    assert force.args["wrench"] == (0, 0, -7, 0, 0, 0)


def test_peg_tree_matches_skireil(peg):
    assert shape(plan_task(peg).tree) == (
        "->*", "plan",
        GOTO,
        ("->", "PegInsertion", "set_goal_from_object",
         ("||FS", "PegInsertion.insert", "goal_pose", "change_stiffness", "apply_force", "overlay_spiral",
          "ee_pose_distance")),
    )
    leaves = {n.primitive: n for n in plan_task(peg).tree.leaves()[2:]}
    assert leaves["change_stiffness"].args["stiffness"] == (500, 500, 0, 50, 50, 50)
    assert leaves["ee_pose_distance"].args["threshold"] == 0.04
    assert dict(leaves["apply_force"].params) == {"force_z": "PegInsertion.force"}
    assert dict(leaves["overlay_spiral"].params) == {
        "radius": "PegInsertion.radius", "path_velocity": "PegInsertion.path_velocity",
    }
    assert leaves["overlay_spiral"].args == {"pitch": 0.0015}  # a constant: the library's, as peg.yaml sets it
    # the insertion goal is the box's origin (SkiREIL: its centre); with the hole's opening
    # 0.05 m above it, the 0.04 m distance check succeeds once the peg is 0.01 m deep (success)
    goal = leaves["set_goal_from_object"]
    assert goal.args["object"] == "BoxWithHole-1" and goal.args["mjcf_body"] == "box"
    assert goal.args["offset"] == (0, 0, 0)
    box = peg.objects["BoxWithHole-1"]
    assert box.size[2] - leaves["ee_pose_distance"].args["threshold"] == pytest.approx(peg.success.depth)


@pytest.mark.parametrize("name", ["push", "peg"])
def test_leaves_use_the_vocabulary_and_every_learnable_parameter(request, name):
    scn = request.getfixturevalue(name)
    leaves = plan_task(scn).tree.leaves()
    assert {leaf.primitive for leaf in leaves} <= set(PRIMITIVES)
    used = [p for leaf in leaves for p in leaf.params.values()]
    assert sorted(used) == sorted(plan_task(scn).parameter_names)  # each exactly once, nothing unknown


def _run(tree: Node, successes_after, ticks: int):
    """Ticks ``tree`` in a scripted world: ee_pose_distance succeeds on its n-th consecutive
    active tick (n = successes_after, or successes_after(leaf)), set_goal_from_object succeeds
    at once, every other leaf holds (RUNNING)."""
    needed = successes_after if callable(successes_after) else (lambda node: successes_after)
    interp = Interpreter(tree)
    streak: dict[int, int] = {}
    trace = []
    for _ in range(ticks):
        active_before = set(streak)

        def leaf(node_id, node):
            if node.primitive == "set_goal_from_object":
                return Status.SUCCESS
            if node.primitive == "ee_pose_distance":
                streak[node_id] = streak.get(node_id, 0) + 1 if node_id in active_before else 1
                return Status.SUCCESS if streak[node_id] >= needed(node) else Status.RUNNING
            return Status.RUNNING

        result = interp.tick(leaf)
        for node_id in list(streak):  # a distance check not ticked starts its count again
            if node_id not in result.active_leaves:
                del streak[node_id]
        trace.append((result.status, [interp.nodes[i] for i in result.active_leaves]))
    return trace


def test_push_tree_runs_its_phases_in_order(push):
    trace = _run(plan_task(push).tree, successes_after=3, ticks=7)
    assert [status for status, _ in trace] == [Status.RUNNING] * 6 + [Status.SUCCESS]

    def goals(leaves):
        return [(n.args["object"], n.params.get("offset_x")) for n in leaves if n.primitive == "set_goal_from_object"]

    def holding(leaves, primitive):
        return any(n.primitive == primitive for n in leaves)

    # tick: which goals are set, is the push stiffness / the downward force held
    table = [(goals(leaves), holding(leaves, "change_stiffness"), holding(leaves, "apply_force")) for _, leaves in trace]
    approach, start, goal = ("ObjectToBePushed-1", None), ("ObjectToBePushed-1", "Push.offset_x_start"), ("ObjectGoalPose-1", "Push.offset_x_goal")
    assert table == [
        ([approach], False, False),
        ([approach], False, False),
        ([approach, start], True, False),  # GoToLinear done: the push starts in the same tick
        ([start], True, False),
        ([start, goal], True, True),  # at the start offset: push to the goal pressing down
        ([goal], True, True),
        ([goal], False, False),  # at the goal: the ParallelFs ends before its holds are ticked
    ]


def test_peg_tree_keeps_searching_while_not_inserted(peg):
    # The approach is reached on the 2nd tick; the insertion's distance check never succeeds.
    never = 10**9
    approach = peg.skills["GoToLinear"].parameter("threshold").default
    trace = _run(plan_task(peg).tree, lambda leaf: 2 if leaf.args["threshold"] == approach else never, ticks=6)
    assert all(status == Status.RUNNING for status, _ in trace)
    insertion = ["set_goal_from_object", "goal_pose", "change_stiffness", "apply_force", "overlay_spiral", "ee_pose_distance"]
    assert [[n.primitive for n in leaves] for _, leaves in trace] == [
        ["set_goal_from_object", "goal_pose", "ee_pose_distance"],
        ["set_goal_from_object", "goal_pose", "ee_pose_distance"] + insertion,
    ] + [insertion] * 4


def test_peg_tree_succeeds_once_inserted(peg):
    trace = _run(plan_task(peg).tree, successes_after=2, ticks=3)
    assert [status for status, _ in trace] == [Status.RUNNING, Status.RUNNING, Status.SUCCESS]


def test_a_skill_used_twice_gets_numbered_parameters(push):
    plan = [
        "(gotolinear iiwa-1 home-1 objecttobepushed-1)",
        "(push iiwa-1 objecttobepushed-1 objectgoalpose-1)",
        "(PUSH iiwa-1 objecttobepushed-1 home-1)",
    ]
    steps = ground_plan(push, plan)
    assert [s.label for s in steps] == ["GoToLinear", "Push", "Push#2"]
    assert dict(steps[2].arguments) == {"robot": "iiwa-1", "workpiece": "ObjectToBePushed-1", "goal": "Home-1"}
    tree, parameters = plan_to_tree(push, steps)
    names = [p.name for p in parameters]
    assert names == list(plan_task(push).parameter_names) + [n.replace("Push.", "Push#2.") for n in plan_task(push).parameter_names]
    assert sorted(p for leaf in tree.leaves() for p in leaf.params.values()) == sorted(names)


def test_a_parameter_not_marked_learnable_becomes_a_fixed_argument(peg):
    skill = peg.skills["PegInsertion"]
    fixed = tuple(dataclasses.replace(p, learnable=False) if p.name == "radius" else p for p in skill.parameters)
    skills = MappingProxyType({**peg.skills, "PegInsertion": dataclasses.replace(skill, parameters=fixed)})
    scn = dataclasses.replace(peg, skills=skills)
    tree, parameters = plan_to_tree(scn, plan_task(peg).steps)
    assert [p.name for p in parameters] == ["PegInsertion.force", "PegInsertion.path_velocity"]
    spiral = next(n for n in tree.leaves() if n.primitive == "overlay_spiral")
    assert spiral.args == {"radius": 0.0, "pitch": 0.0015} and "radius" not in spiral.params


@pytest.mark.parametrize(
    "plan, message",
    [
        (["(fly iiwa-1 home-1)"], "names no skill"),
        (["(gotolinear iiwa-1 home-1)"], "takes 3 arguments"),
        (["(gotolinear iiwa-1 home-1 moon-1)"], "unknown object 'moon-1'"),
    ],
)
def test_plans_that_do_not_fit_the_library_are_rejected(push, plan, message):
    with pytest.raises(PlanError, match=message):
        ground_plan(push, plan)


def test_an_empty_plan_is_rejected(push):
    with pytest.raises(PlanError, match="goal already holds"):
        plan_to_tree(push, ())


def test_the_push_starts_turned_to_the_workpiece_and_goes_straight(push, peg):
    # Every goal turns the square tool to its element, except the push's end, which keeps the
    # pusher's yaw: turning it on the way twists the workpiece off the push line.
    def orientations(tree):
        return [(n.name, n.args["object"], n.args["orientation"]) for n in tree.leaves() if n.primitive == "set_goal_from_object"]

    assert [o for _, _, o in orientations(plan_task(push).tree)] == ["tool_down_aligned", "tool_down_aligned", "tool_down"]
    assert orientations(plan_task(push).tree)[2][1] == "ObjectGoalPose-1"
    assert {o for _, _, o in orientations(plan_task(peg).tree)} == {"tool_down_aligned"}
