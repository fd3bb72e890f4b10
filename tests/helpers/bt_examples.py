"""Example eBTs shared by the compiled-tick tests and benchmarks/bt_tick.py."""

from mjxskill.ebt import nodes as N

STIFFNESS = {"stiffness": (700.0, 700.0, 700.0, 50.0, 50.0, 50.0)}
START_OFFSETS = {"offset_x": "Push.offset_x_start", "offset_y": "Push.offset_y_start"}
GOAL_OFFSETS = {"offset_x": "Push.offset_x_goal", "offset_y": "Push.offset_y_goal"}


def press(force_z: float = -7.0) -> dict:
    """apply_force arguments pressing down with ``force_z`` N."""
    return {"force": (0.0, 0.0, force_z, 0.0, 0.0, 0.0)}


def push_tree(force_z: float = -7.0) -> N.Node:
    """SkiREIL's Push skill: SerialStar of two ParallelFs blocks, each a linear motion with changed
    stiffness, the second also pressing down."""
    return N.serial_star(
        "Push",
        N.parallel_fs(
            "ToStart",
            N.action("GoToStart", "go_to_linear_offset", params=START_OFFSETS),
            N.action("Stiffen1", "change_stiffness", args=STIFFNESS),
        ),
        N.parallel_fs(
            "PushToGoal",
            N.action("GoToGoal", "go_to_linear_offset", params=GOAL_OFFSETS),
            N.action("Stiffen2", "change_stiffness", args=STIFFNESS),
            N.action("Press", "apply_force", args=press(force_z)),
        ),
    )
