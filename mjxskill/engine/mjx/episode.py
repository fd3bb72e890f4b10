"""One episode of one world: the compiled BT at ``bt_hz`` over the impedance controller and MJX at
``control_hz``, as two nested ``lax.scan``s. Written for one world; batching is a wrapper.

Per BT tick: leaf statuses -> compiled tick -> leaf effects -> ``steps_per_tick`` control steps
(motion generator -> controller -> ``mjx.step``) -> rewards of the tick. Nothing is stored per
step or per tick: the scan carries running totals only, so memory does not grow with the
episode length.

Containment: after every tick, a world whose state is not finite, whose joints spin faster than
``MAX_QVEL`` or whose free objects sink below ``MIN_OBJECT_Z`` is marked diverged and frozen at
its last good state; its rewards are replaced by each term's worst value for the whole episode
and it counts as a failure, so one exploding world never poisons its batch or the optimizer.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import jax
import jax.numpy as jnp
from mujoco import mjx

from mjxskill.bt_compiled import CompiledTree, init_state, started_leaves, tick
from mjxskill.ebt.nodes import Status
from mjxskill.engine.common.arrays import JAX
from mjxskill.engine.common.bindings import FREE, MOCAP, nominal_poses
from mjxskill.engine.common.rewards import Observation, RewardTerm, raw_rewards
from mjxskill.engine.common.success import success
from mjxskill.engine.mjx.leaves import Blackboard, LeafPrograms, LeafWorld, advance, init_blackboard, reference_pose
from mjxskill.engine.common.health import free_object_z_addresses, healthy_state
from mjxskill.engine.common.types import EpisodeResult, EpisodeSetup, TickRecord
from mjxskill.engine.common.worlds import Worlds, world_pair_friction
from mjxskill.engine.mjx.controller import (
    N_ARM,
    ControllerState,
    impedance_control,
    init_controller_state,
    make_command,
    tool_pose,
)

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.bt_compiled.tick import BTState


class EpisodeSpec(NamedTuple):
    """Everything static about a compiled episode (host values, closed over by the traced
    function): the compiled tree, its leaf programs, the reward terms and the engine-independent
    ``setup``."""

    ct: CompiledTree
    leaves: LeafPrograms
    terms: tuple[RewardTerm, ...]
    setup: EpisodeSetup


class _Carry(NamedTuple):
    data: mjx.Data
    ctrl: ControllerState
    bb: Blackboard
    bt: BTState
    done: jax.Array  # the root finished
    status: jax.Array  # the root's last status
    done_tick: jax.Array
    diverged: jax.Array
    totals: jax.Array
    peak_commanded_force: jax.Array
    peak_contact_force: jax.Array
    contact_force_sum: jax.Array  # over the control steps


def initial_data(spec: EpisodeSpec, model: mjx.Model, template: mjx.Data, world: Worlds) -> mjx.Data:
    """MJX data at the world's initial conditions, kinematics computed."""
    qpos = template.qpos.at[jnp.asarray(spec.setup.bindings.arm_qpos)].set(world.arm_qpos)
    mocap_pos, mocap_quat = template.mocap_pos, template.mocap_quat
    for k, slot in enumerate(spec.setup.bindings.slots):
        if slot.how == FREE:
            qpos = qpos.at[slot.qpos_adr : slot.qpos_adr + 3].set(world.object_pos[k])
            qpos = qpos.at[slot.qpos_adr + 3 : slot.qpos_adr + 7].set(world.object_quat[k])
        elif slot.how == MOCAP:
            mocap_pos = mocap_pos.at[slot.mocap_id].set(world.object_pos[k])
            mocap_quat = mocap_quat.at[slot.mocap_id].set(world.object_quat[k])
    data = template.replace(qpos=qpos, qvel=jnp.zeros_like(template.qvel), mocap_pos=mocap_pos, mocap_quat=mocap_quat)
    return mjx.forward(model, data)


def world_model(spec: EpisodeSpec, model: mjx.Model, world: Worlds) -> mjx.Model:
    """The model with this world's friction on the randomized object's contact pairs."""
    if not spec.setup.bindings.randomized_pairs:
        return model
    return model.replace(pair_friction=world_pair_friction(model.pair_friction, spec.setup.bindings.randomized_pairs,
                                                           world.friction, JAX))


def slot_poses(spec: EpisodeSpec, data: mjx.Data, world: Worlds):
    """(K, 3), (K, 4): current poses of the bound objects (free bodies move; others do not)."""
    pos, quat = world.object_pos, world.object_quat
    for k, slot in enumerate(spec.setup.bindings.slots):
        if slot.how == FREE:
            pos = pos.at[k].set(data.xpos[slot.body_id])
            quat = quat.at[k].set(data.xquat[slot.body_id])
    return pos, quat


def _healthy(spec: EpisodeSpec, data: mjx.Data) -> jax.Array:
    return healthy_state(JAX, data.qpos, data.qvel, free_object_z_addresses(spec.setup.bindings))


def _where(cond, new, old):
    return jax.tree.map(lambda n, o: jnp.where(cond, n, o), new, old)


def run_episode(
    spec: EpisodeSpec, model: mjx.Model, template: mjx.Data, params: jax.Array, world: Worlds, record: bool = False
):
    """Rolls out parameter vector ``params`` (P,) in ``world`` (unbatched fields).

    Returns the EpisodeResult, or (EpisodeResult, TickRecord with a leading (T,) axis) when
    ``record`` is True.
    """
    model = world_model(spec, model, world)
    carry = _initial_carry(spec, model, template, world)
    bt_tick = _bt_tick_fn(spec, model, params, world, record)
    c, trace = jax.lax.scan(bt_tick, carry, jnp.arange(spec.setup.ticks, dtype=jnp.int32))
    result = _episode_result(spec, c, world)
    return (result, trace) if record else result


def _initial_carry(spec: EpisodeSpec, model: mjx.Model, template: mjx.Data, world: Worlds) -> _Carry:
    """The scan's carry before the first tick: the world's initial conditions, the reference at
    the tool's pose, a fresh tree and zero totals."""
    data = initial_data(spec, model, template, world)
    tool_pos, tool_quat = tool_pose(spec.setup.ctrl, model, data)
    bb = init_blackboard(tool_pos, tool_quat, spec.setup.default_stiffness, len(spec.ct.leaves))
    ref = reference_pose(bb)
    ctrl = init_controller_state(data, make_command(ref.pos, ref.quat, bb.wrench, bb.stiffness))
    return _Carry(
        data=data,
        ctrl=ctrl,
        bb=bb,
        bt=init_state(spec.ct),
        done=jnp.zeros((), bool),
        status=jnp.int32(Status.RUNNING),
        done_tick=jnp.int32(-1),
        diverged=jnp.zeros((), bool),
        totals=jnp.zeros(len(spec.terms), jnp.float32),
        peak_commanded_force=jnp.zeros((), jnp.float32),
        peak_contact_force=jnp.zeros((), jnp.float32),
        contact_force_sum=jnp.zeros((), jnp.float32),
    )


def _control_step_fn(spec: EpisodeSpec, model: mjx.Model, nullspace_target: jax.Array):
    """The body of the inner scan, one control step: motion generator -> controller ->
    ``mjx.step``; its carry is (data, controller state, blackboard, the tool's measured contact
    force summed and its peak over the tick's steps)."""
    dt = spec.setup.ctrl.dt
    force_sensors = jnp.asarray(spec.setup.bindings.force_sensors, jnp.int32)

    def control_step(carry, _):
        data, ctrl, bb, force_sum, force_peak = carry
        ref = reference_pose(bb)
        command = make_command(ref.pos, ref.quat, bb.wrench, bb.stiffness)
        tau, ctrl = impedance_control(spec.setup.ctrl, model, data, command, nullspace_target, ctrl)
        data = mjx.step(model, data.replace(ctrl=data.ctrl.at[:N_ARM].set(tau)))
        # the tool's touch sensors, computed by mjx.step: the step's measured contact force
        force = jnp.sum(data.sensordata[force_sensors])
        return (data, ctrl, advance(bb, dt), force_sum + force, jnp.maximum(force_peak, force)), None

    return control_step


def _bt_tick_fn(spec: EpisodeSpec, model: mjx.Model, params: jax.Array, world: Worlds, record: bool):
    """The body of the outer scan, one BT tick: the tree ticks on its leaves' statuses, the leaf
    effects set the blackboard, ``steps_per_tick`` control steps run, a diverged world is frozen
    (module doc), and the tick's rewards are added up; with ``record`` it also returns the
    tick's TickRecord."""
    nominal_pos = jnp.asarray(nominal_poses(spec.setup.bindings)[0])
    control_step = _control_step_fn(spec, model, world.arm_qpos)

    def bt_tick(c: _Carry, t):
        tool_pos, tool_quat = tool_pose(spec.setup.ctrl, model, c.data)
        # The skills see the world *model* (the YAML's nominal poses), not the randomized world:
        # that mismatch is what the learned parameters must be robust to.
        leaf_world = LeafWorld(tool_pos, tool_quat, nominal_pos)
        bt, root, active, bb = _tick_tree(spec, c, leaf_world, params)
        zero = jnp.zeros((), jnp.float32)
        (data, ctrl, bb, force_sum, force_peak), _ = jax.lax.scan(
            control_step, (c.data, c.ctrl, bb, zero, zero), None, length=spec.setup.steps_per_tick)

        healthy = _healthy(spec, data) & ~c.diverged
        data, ctrl, bb = _where(healthy, (data, ctrl, bb), (c.data, c.ctrl, c.bb))
        finished = root != Status.RUNNING
        obs = _observation(spec, model, world, data, ctrl, bb, root, force_sum)
        raw = raw_rewards(spec.terms, obs, JAX) if spec.terms else jnp.zeros(0, jnp.float32)
        totals = c.totals + raw
        trace = (TickRecord(data.qpos, data.mocap_pos, data.mocap_quat, obs.tool_pos, obs.ref_pos, root, active, raw)
                 if record else None)
        return (
            _Carry(
                data=data,
                ctrl=ctrl,
                bb=bb,
                bt=bt,
                done=c.done | finished,
                status=root,
                done_tick=jnp.where(~c.done & finished, t, c.done_tick),
                diverged=~healthy,
                totals=totals,
                peak_commanded_force=jnp.maximum(c.peak_commanded_force, jnp.linalg.norm(ctrl.wrench[:3])),
                peak_contact_force=jnp.where(healthy, jnp.maximum(c.peak_contact_force, force_peak), c.peak_contact_force),
                contact_force_sum=jnp.where(healthy, c.contact_force_sum + force_sum, c.contact_force_sum),
            ),
            trace,
        )

    return bt_tick


def _tick_tree(spec: EpisodeSpec, c: _Carry, leaf_world: LeafWorld, params: jax.Array):
    """The compiled tick on the leaves' statuses, then the active leaves' effects: (tree state,
    root status, active leaves, blackboard). Once the root has finished the tree is no longer
    ticked: it keeps its state and status and every leaf is idle."""
    live = c.bt.live[jnp.asarray(spec.ct.leaf_ids)]
    leaf_status = spec.leaves.status(c.bb, leaf_world, params, live)
    bt, root, active = tick(spec.ct, c.bt, leaf_status)
    started = started_leaves(spec.ct, c.bt, active)
    active = active & ~c.done
    bt = _where(c.done, c.bt, bt)
    root = jnp.where(c.done, c.status, root)
    bb = spec.leaves.effects(c.bb, active, started, leaf_world, params)
    return bt, root, active, bb


def _observation(spec: EpisodeSpec, model: mjx.Model, world: Worlds, data: mjx.Data, ctrl: ControllerState,
                 bb: Blackboard, root: jax.Array, force_sum: jax.Array) -> Observation:
    """What the reward terms see at the end of a tick."""
    tool_pos, tool_quat = tool_pose(spec.setup.ctrl, model, data)
    slot_pos, slot_quat = slot_poses(spec, data, world)
    return Observation(
        tool_pos=tool_pos,
        tool_quat=tool_quat,
        ref_pos=reference_pose(bb).pos,
        slot_pos=slot_pos,
        slot_quat=slot_quat,
        wrench=ctrl.wrench,
        bt_succeeded=root == Status.SUCCESS,
        contact_force=force_sum / spec.setup.steps_per_tick,
    )


def _episode_result(spec: EpisodeSpec, c: _Carry, world: Worlds) -> EpisodeResult:
    """The EpisodeResult from the final carry; a diverged world gets each term's worst reward
    for the whole episode, counts as a failure and has unknown (NaN) contact forces."""
    n_terms = len(spec.terms)
    worst = jnp.asarray([t.worst_raw * spec.setup.ticks for t in spec.terms], jnp.float32).reshape(n_terms)
    totals = jnp.where(c.diverged, worst, c.totals)
    success, pos_err, rot_err, depth = _success(spec, c.data, world)
    return EpisodeResult(
        reward_totals=totals,
        success=success & ~c.diverged,
        diverged=c.diverged,
        bt_status=jnp.where(c.diverged, jnp.int32(Status.FAILURE), c.status),
        bt_done_tick=c.done_tick,
        position_error=pos_err,
        orientation_error=rot_err,
        insertion_depth=depth,
        peak_commanded_force=c.peak_commanded_force,
        # a diverged world's forces are not known: NaN, which meets no force limit
        peak_contact_force=jnp.where(c.diverged, jnp.nan, c.peak_contact_force),
        mean_contact_force=jnp.where(c.diverged, jnp.nan,
                                     c.contact_force_sum / (spec.setup.ticks * spec.setup.steps_per_tick)),
    )


def _success(spec: EpisodeSpec, data: mjx.Data, world: Worlds):
    """(success, position error, orientation error, insertion depth) at the end of the episode."""
    slot_pos, slot_quat = slot_poses(spec, data, world)
    return success(spec.setup.success, data.site_xpos[spec.setup.ctrl.site_id], slot_pos, slot_quat, JAX)
