"""Leaf programs: what each eBT primitive (``mjxskill.ebt.primitives``) does to the controller
command, as pure JAX over a small blackboard state.

Every BT tick runs in two phases, so that no Python runs per tick and the tick itself stays the
compiled state machine of ``mjxskill.bt_compiled``:

1. ``leaf_status``: the status each leaf would return if ticked, from the blackboard and the world
   as they are before the tick. ``set_goal_from_object`` succeeds at once; the "holding" leaves
   (``goal_pose``, ``change_stiffness``, ``apply_force``, ``overlay_spiral``) run until preempted;
   ``ee_pose_distance`` succeeds once the tool is within its threshold of the motion goal, but
   only when it was already running on the last tick, so the motion generator has run on that
   goal for at least one tick (a monitor must observe before it can judge); ``wait`` succeeds
   after its duration.
2. ``apply_effects``: the leaves the tick activated write the blackboard, in tick order (so a goal
   written by ``set_goal_from_object`` reaches the ``goal_pose`` ticked after it in the same
   tick). Stiffness, wrench and the spiral are held only while their leaf is active: a halted
   ``change_stiffness`` falls back to the robot's default stiffness, a halted ``apply_force`` to
   no force (the controller ramps both at its rate limits).

The motion generator starts a new straight-line trajectory from the current reference to the
blackboard goal whenever a ``goal_pose`` leaf starts (afresh: newly ticked, or restarted by a
decorator); the spiral restarts whenever an ``overlay_spiral`` leaf starts.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjxskill.bt_compiled import CompiledTree
from mjxskill.ebt.nodes import Status
from mjxskill.ebt.primitives import SPIRAL_NORMAL, LeafRegistry, goal_orientation
from mjxskill.engine.common.bindings import SceneBindings
from mjxskill.engine.common.leaf_inputs import LeafInput, force_inputs, leaf_input, spiral_inputs, wait_ticks
from mjxskill.engine.mjx.motion import MotionLimits, Pose, SpiralState, init_spiral, linear_trajectory, spiral_step
from mjxskill.engine.common.arrays import JAX
from mjxskill.engine.common.rotations import quat_mul
from mjxskill.engine.common.tool import TOOL_DOWN, TOOL_SYMMETRY, tool_yaw as common_tool_yaw
from mjxskill.errors import quote



class Blackboard(NamedTuple):
    """Per-world state the leaf programs share (all float32 unless noted).

    goal_pos (3,), goal_quat (4,): the last pose ``set_goal_from_object`` wrote.
    mg_start (Pose), mg_goal (Pose), mg_time (): the motion generator's trajectory and the time
      since it started, s.
    stiffness (6,), wrench (6,): commanded stiffness and feed-forward wrench (before the
      controller's rate limits).
    spiral (SpiralState), spiral_on () bool, spiral_params (3,): radius cap m, path velocity m/s,
      pitch m; spiral_axes (2, 3): the unit vectors spanning the spiral's plane.
    leaf_ticks (L,) int32: ticks each leaf has been active since it (re)started, 0 when idle.
    """

    goal_pos: jax.Array
    goal_quat: jax.Array
    mg_start: Pose
    mg_goal: Pose
    mg_time: jax.Array
    stiffness: jax.Array
    wrench: jax.Array
    spiral: SpiralState
    spiral_on: jax.Array
    spiral_params: jax.Array
    leaf_ticks: jax.Array
    spiral_axes: jax.Array


def init_blackboard(tool_pos, tool_quat, default_stiffness, n_leaves: int) -> Blackboard:
    """The reference starts where the tool is, with the default stiffness and no force."""
    pose = Pose(tool_pos, tool_quat)
    return Blackboard(
        goal_pos=tool_pos,
        goal_quat=tool_quat,
        mg_start=pose,
        mg_goal=pose,
        mg_time=jnp.zeros((), jnp.float32),
        stiffness=jnp.asarray(default_stiffness, jnp.float32),
        wrench=jnp.zeros(6, jnp.float32),
        spiral=init_spiral(),
        spiral_on=jnp.zeros((), bool),
        spiral_params=jnp.zeros(3, jnp.float32),
        leaf_ticks=jnp.zeros(n_leaves, jnp.int32),
        spiral_axes=jnp.asarray(spiral_axes(SPIRAL_NORMAL)),
    )


def spiral_axes(normal) -> np.ndarray:
    """(2, 3) float32: the unit vectors spanning the plane normal to ``normal`` (3,), computed on
    the host as ``mjxskill.engine.mjx.motion.plane_basis`` computes them (a constant of the trace)."""
    n = np.asarray(normal, np.float32) / np.linalg.norm(np.asarray(normal, np.float32))
    helper = np.array([0, 0, 1] if abs(n[2]) < 0.9 else [1, 0, 0], np.float32)
    e1 = np.cross(helper, n)
    e1 = e1 / np.linalg.norm(e1)
    return np.stack([e1, np.cross(n, e1)]).astype(np.float32)


def reference_pose(bb: Blackboard, limits: MotionLimits = MotionLimits()) -> Pose:
    """Controller reference: the trajectory at mg_time plus the spiral offset when it is on."""
    base = linear_trajectory(bb.mg_start, bb.mg_goal, bb.mg_time, limits)
    spiral = bb.spiral.radius * (jnp.cos(bb.spiral.theta) * bb.spiral_axes[0] + jnp.sin(bb.spiral.theta) * bb.spiral_axes[1])
    offset = jnp.where(bb.spiral_on, spiral, 0.0)
    return Pose(base.pos + offset, base.quat)


def advance(bb: Blackboard, dt: float) -> Blackboard:
    """One control period of the motion generator and the spiral."""
    radius, velocity, pitch = bb.spiral_params[0], bb.spiral_params[1], bb.spiral_params[2]
    spiral = jax.tree.map(
        lambda new, old: jnp.where(bb.spiral_on, new, old), spiral_step(bb.spiral, radius, velocity, pitch, dt), bb.spiral
    )
    return bb._replace(mg_time=bb.mg_time + dt, spiral=spiral)


def _yaw_of(object_quat) -> float:
    """Yaw (rad) of an object's orientation (w, x, y, z), about world z."""
    w, x, y, z = (float(v) for v in object_quat)
    return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def tool_yaw(quat):
    """Yaw (rad) of a tool-down orientation (w, x, y, z), traced (``common.tool.tool_yaw``)."""
    return common_tool_yaw(quat, JAX)


def tool_down_aligned(current_quat, object_yaw, tilt=None):
    """set_goal_from_object's orientation: the tool pointing down with its faces aligned to
    ``object_yaw`` (rad), choosing among the tool's symmetric yaws the one nearest the current one
    (a square peg fits a square hole only within a few degrees of alignment), tilted by ``tilt``
    (roll, pitch) rad about the turned frame's x then y axes (None: not tilted)."""
    yaw = tool_yaw(current_quat)
    delta = jnp.mod(object_yaw - yaw + TOOL_SYMMETRY / 2, TOOL_SYMMETRY) - TOOL_SYMMETRY / 2
    target = yaw + delta
    turn = jnp.stack([jnp.cos(target / 2), jnp.zeros_like(target), jnp.zeros_like(target), jnp.sin(target / 2)])
    down = jnp.asarray(TOOL_DOWN, jnp.float32)
    if tilt is not None:
        roll, pitch = tilt
        zero = jnp.zeros_like(roll)
        about_x = jnp.stack([jnp.cos(roll / 2), jnp.sin(roll / 2), zero, zero])
        about_y = jnp.stack([jnp.cos(pitch / 2), zero, jnp.sin(pitch / 2), zero])
        down = quat_mul(quat_mul(about_y, about_x), down)
    return quat_mul(turn, down)


class LeafWorld(NamedTuple):
    """What leaf programs read: the tool pose and the world model's object positions (K, 3)."""

    tool_pos: jax.Array
    tool_quat: jax.Array
    slot_pos: jax.Array


def _input(leaf, name: str, parameter_index: dict) -> Callable:
    """A leaf input as a function of the parameter vector (``leaf_inputs.leaf_input``)."""
    return _reader(leaf_input(leaf, name, parameter_index))


def _reader(source: LeafInput) -> Callable:
    if source.index is not None:
        return lambda params: params[source.index]
    return lambda params: jnp.float32(source.value)


class LeafPrograms(NamedTuple):
    """status(bb, world, params, live (L,)) -> (L,) int32: ``live`` marks leaves still running on
    from the last tick. effects(bb, active (L,), started (L,), world, params) -> bb: ``started``
    marks active leaves that start afresh (``bt_compiled.started_leaves``)."""

    status: Callable
    effects: Callable


def build_leaf_programs(
    ct: CompiledTree,
    parameter_names: tuple[str, ...],
    bindings: SceneBindings,
    default_stiffness,
    tick_seconds: float,
) -> LeafPrograms:
    """Leaf programs for the compiled tree's leaves (host-side; the closures trace into jit)."""
    ctx = _Context({name: i for i, name in enumerate(parameter_names)}, bindings, tick_seconds)
    default_stiffness = np.asarray(default_stiffness, np.float32)
    status_fns, effect_fns = [], []
    for i, leaf in enumerate(ct.leaves):
        status, effect = LEAF_PROGRAMS.build(i, leaf, ctx)
        status_fns.append(status)
        effect_fns.append(effect)

    # the loop's status is not used after it
    def status(bb: Blackboard, world: LeafWorld, params, live: jax.Array) -> jax.Array:  # type: ignore[no-redef]
        return jnp.stack([jnp.asarray(f(bb, world, params, live), jnp.int32) for f in status_fns])

    def effects(bb: Blackboard, active: jax.Array, started: jax.Array, world: LeafWorld, params) -> Blackboard:
        # Held effects fall back to their defaults unless an active leaf sets them again.
        bb = bb._replace(
            stiffness=jnp.asarray(default_stiffness),
            wrench=jnp.zeros(6, jnp.float32),
            spiral_on=jnp.zeros((), bool),
        )
        for i, f in enumerate(effect_fns):
            new = f(bb, world, params, started[i])
            bb = jax.tree.map(lambda n, o: jnp.where(active[i], n, o), new, bb)
        return bb._replace(leaf_ticks=jnp.where(active, jnp.where(started, 1, bb.leaf_ticks + 1), 0))

    return LeafPrograms(status, effects)


class _Context(NamedTuple):
    """What leaf programs are built from: parameter name -> index in the parameter vector, the
    scene bindings and the BT tick period (s)."""

    index: dict  # type: ignore[assignment]  # a field named like tuple.index, which it shadows
    bindings: SceneBindings
    tick_seconds: float


def _running(bb, world, params, live):
    return Status.RUNNING


def _keep(bb, world, params, fresh):
    return bb


# primitive -> (leaf number, leaf, _Context) -> (status, effect): every mjxskill.ebt.primitives.PRIMITIVES
LEAF_PROGRAMS = LeafRegistry()


@LEAF_PROGRAMS.register
def _set_goal_from_object(i: int, leaf, ctx: _Context):
    index, bindings = ctx.index, ctx.bindings
    obj = leaf.args.get("object")
    if obj not in bindings.slot_of:
        raise ValueError(f"leaf {quote(leaf.name)}: object {quote(obj)} is not bound to the scene")
    slot = bindings.slot_of[obj]
    fixed = np.asarray(leaf.args.get("offset", (0.0, 0.0, 0.0)), np.float32)
    dx, dy = _input(leaf, "offset_x", index), _input(leaf, "offset_y", index)
    roll, pitch, yaw = (_input(leaf, f"tool_{k}", index) for k in ("roll", "pitch", "yaw"))
    tilted = any(f"tool_{k}" in leaf.args or f"tool_{k}" in leaf.params for k in ("roll", "pitch"))
    turned = "tool_yaw" in leaf.args or "tool_yaw" in leaf.params

    aligned = goal_orientation(leaf) == "tool_down_aligned"
    object_yaw = _yaw_of(bindings.slots[slot].quat)

    def set_goal(bb, world, params, fresh):
        offset = jnp.asarray(fixed) + jnp.stack([dx(params), dy(params), jnp.float32(0.0)])
        current = reference_pose(bb).quat
        target = object_yaw if aligned else tool_yaw(current)
        if turned:  # (the untouched default keeps the shipped skills' numbers bit for bit)
            target = target + jnp.deg2rad(yaw(params))
        tilt = (jnp.deg2rad(roll(params)), jnp.deg2rad(pitch(params))) if tilted else None
        quat = tool_down_aligned(current, target, tilt)
        return bb._replace(goal_pos=world.slot_pos[slot] + offset, goal_quat=quat)

    return (lambda bb, world, params, live: Status.SUCCESS), set_goal


@LEAF_PROGRAMS.register
def _goal_pose(i: int, leaf, ctx: _Context):

    def start_motion(bb, world, params, fresh):
        ref = reference_pose(bb)
        start = jax.tree.map(lambda n, o: jnp.where(fresh, n, o), ref, bb.mg_start)
        goal = jax.tree.map(lambda n, o: jnp.where(fresh, n, o), Pose(bb.goal_pos, bb.goal_quat), bb.mg_goal)
        return bb._replace(mg_start=start, mg_goal=goal, mg_time=jnp.where(fresh, 0.0, bb.mg_time))

    return _running, start_motion


@LEAF_PROGRAMS.register
def _change_stiffness(i: int, leaf, ctx: _Context):
    stiffness = np.asarray(leaf.args["stiffness"], np.float32)
    return _running, lambda bb, world, params, fresh: bb._replace(stiffness=jnp.asarray(stiffness))


@LEAF_PROGRAMS.register
def _apply_force(i: int, leaf, ctx: _Context):
    index = ctx.index
    base, sources = force_inputs(leaf, index)
    base = base.astype(np.float32)
    overrides = [(axis, _reader(source)) for axis, source in sources]

    def apply_force(bb, world, params, fresh):
        wrench = jnp.asarray(base)
        for axis, value in overrides:
            wrench = wrench.at[axis].set(value(params))
        return bb._replace(wrench=wrench)

    return _running, apply_force


@LEAF_PROGRAMS.register
def _overlay_spiral(i: int, leaf, ctx: _Context):
    radius, velocity, pitch = (_reader(source) for source in spiral_inputs(leaf, ctx.index))
    axes = spiral_axes(leaf.args.get("normal", SPIRAL_NORMAL))

    def overlay(bb, world, params, fresh):
        spiral = jax.tree.map(lambda o: jnp.where(fresh, jnp.zeros_like(o), o), bb.spiral)
        p = jnp.stack([radius(params), velocity(params), pitch(params)])
        return bb._replace(spiral=spiral, spiral_on=jnp.ones((), bool), spiral_params=p, spiral_axes=jnp.asarray(axes))

    return _running, overlay


@LEAF_PROGRAMS.register
def _ee_pose_distance(i: int, leaf, ctx: _Context):
    threshold = float(leaf.args["threshold"])

    def reached(bb, world, params, live):
        close = jnp.linalg.norm(world.tool_pos - bb.mg_goal.pos) < threshold
        return jnp.where(live[i] & close, Status.SUCCESS, Status.RUNNING)

    return reached, _keep


@LEAF_PROGRAMS.register
def _wait(i: int, leaf, ctx: _Context):
    tick_seconds = ctx.tick_seconds
    ticks = wait_ticks(leaf, tick_seconds)
    return (lambda bb, world, params, live: jnp.where(live[i] & (bb.leaf_ticks[i] >= ticks), Status.SUCCESS, Status.RUNNING)), _keep
