"""The native engine's batched stepping (``mjxskill.engine.native.batched``: MuJoCo batches and the
compiled law of ``mjxskill.engine.native.kernels``) against its references.

- The compiled law against the numpy law (``batched_impedance_control`` of
  ``mjxskill.engine.native_reference``, written operation for operation as the kernel, and
  itself tested against the plain loop's ``mj_jacSite``/``mju_*`` law with BLAS and LAPACK, to
  rounding) on states MuJoCo produced: the same torques bit for bit, the Jacobian assembled as
  ``mj_jac`` does; its ``mju_mat2Quat`` against MuJoCo's on random rotations, bit for bit.
- Whole episodes against the numpy lockstep (the reference's ``run_lockstep``) on push and on
  the round peg (whose mesh contacts turn a last-bit difference into a visible one within
  seconds): every result bit for bit on 3 s episodes; on full-length ones (the peg's spiral
  runs, trees finish) every result but the reward totals, which may differ in the last bit
  (the rewards over rows here, one episode's there).
- Results bit-identical whatever the threads of the batch (1, 2, 4), and whichever episodes share it.
- The references of a tick at once (the spiral compiled, the ended motion cached) equal to the
  uncompiled, uncached code to rounding; those of many blackboards in one pass
  (``references_rows``) and of a ``RowsBoard``'s rows (the engine's) bit-identical to each
  blackboard's own, and the reference kept at a tick's end used only while it holds.
- Every leaf status over a ``RowsBoard``'s rows (``LeafStatus.rows``, what the batch's compiled
  tree ticks on) is each blackboard's own status; the effects' rows forms are tested in
  test_board.py. (The compiled tree's tick over rows is tested against the reference
  interpreter in tests/bt_compiled/test_property.py; the whole episodes above tick it.)
"""

import math

import jax
import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mjxskill import load_scenario, plan_task
from mjxskill.engine.common.types import EpisodeResult
from mjxskill.engine.native import NativeRollout
from mjxskill.engine.native.batched import kinematic_chain, run_batched, start_batch
from mjxskill.engine.native.kernels import _mat2quat, impedance_rows
from mjxskill.ebt.nodes import Status
from mjxskill.engine.native.blackboard import NativeBlackboard, references_rows
from blackboards import BLACKBOARD, START_QUAT, blackboard, board_of, finite, unit
from mjxskill.engine.native.leaves import Always, Reached, Waited
from mjxskill.engine.native.motion import LinearMotion, spiral_step
from mjxskill.engine.native_reference import BatchedControllerState, batched_impedance_control, run_lockstep
from mjxskill.sim.controller_config import N_ARM

def flat_worlds(engine, n_sets, seed):
    worlds = engine.sample_worlds(jax.random.key(seed), n_sets)
    w = engine.worlds
    return jax.tree.map(lambda x: np.array(x.reshape((n_sets * w,) + x.shape[2:])), worlds)


def fields_of(results):
    return {f: np.array([getattr(r, f) for r in results]) for f in EpisodeResult._fields}


@pytest.fixture(scope="module", params=["push", "peg"])
def engine(request):
    scn = load_scenario(request.param)
    return NativeRollout(scn, plan_task(scn), worlds=3, episode_seconds=3.0)


def params_for(engine, n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(*engine.task.bounds, size=(n, len(engine.task.parameter_names)))


def test_whole_episodes_equal_the_numpy_lockstep_bit_for_bit(engine):
    params = np.repeat(params_for(engine, 3), engine.worlds, axis=0)
    worlds = flat_worlds(engine, 3, seed=1)
    batched, lockstep = fields_of(run_batched(engine, params, worlds)), fields_of(run_lockstep(engine, params, worlds))
    for name in EpisodeResult._fields:
        np.testing.assert_array_equal(batched[name], lockstep[name], err_msg=name)
    assert np.nanmax(batched["peak_contact_force"]) > 1.0  # episodes in contact, where rounding would show


@pytest.mark.parametrize("task", ["push", "peg"])
def test_whole_full_length_episodes_equal_the_numpy_lockstep(task):
    # The scenario's own episode length (12 s push, 18 s peg: the peg's search spiral runs, motions
    # start and end, trees finish): every result bit for bit but the reward totals, which sum
    # each tick's terms computed over rows here and for one episode there (numpy's exp and inner
    # products over rows may round the last bit differently).
    scn = load_scenario(task)
    engine = NativeRollout(scn, plan_task(scn), worlds=3)
    params = np.repeat(params_for(engine, 2), engine.worlds, axis=0)
    worlds = flat_worlds(engine, 2, seed=1)
    batched, lockstep = fields_of(run_batched(engine, params, worlds)), fields_of(run_lockstep(engine, params, worlds))
    for name in EpisodeResult._fields:
        if name == "reward_totals":
            np.testing.assert_allclose(batched[name], lockstep[name], rtol=1e-12, atol=0)
        else:
            np.testing.assert_array_equal(batched[name], lockstep[name], err_msg=name)


def test_results_do_not_depend_on_threads_or_on_the_other_episodes(engine):
    params = np.repeat(params_for(engine, 2, seed=3), engine.worlds, axis=0)
    worlds = flat_worlds(engine, 2, seed=4)
    one = fields_of(run_batched(engine, params, worlds, threads=1))
    two = fields_of(run_batched(engine, params, worlds, threads=2))
    four = fields_of(run_batched(engine, params, worlds, threads=4))
    tail = fields_of(run_batched(engine, params[2:], jax.tree.map(lambda x: x[2:], worlds)))
    for name in EpisodeResult._fields:
        np.testing.assert_array_equal(one[name], two[name], err_msg=name)
        np.testing.assert_array_equal(one[name], four[name], err_msg=name)
        np.testing.assert_array_equal(one[name][2:], tail[name], err_msg=name)


def test_the_compiled_law_gives_the_numpy_laws_torques_on_states_mujoco_made(engine):
    n = 6
    params = np.repeat(params_for(engine, 2, seed=5), engine.worlds, axis=0)[:n]
    batch, f, bad = start_batch(engine, flat_worlds(engine, 2, seed=6))
    assert not bad.any()
    rng = np.random.default_rng(7)
    f["ctrl"][:, :N_ARM] = rng.normal(0.0, 20.0, size=(len(f["ctrl"]), N_ARM))
    batch.step(nstep=25)  # a state away from rest: moving arms, contacts possible
    cfg, model = engine.setup.ctrl, engine.mj_model
    rows = np.arange(n)
    ref_pos = f["site_xpos"][rows, cfg.site_id] + rng.normal(0.0, 0.02, size=(n, 3))
    ref_quat = rng.normal(size=(n, 4))
    ref_quat /= np.linalg.norm(ref_quat, axis=1, keepdims=True)
    cmd_wrench, cmd_stiffness = rng.normal(0.0, 5.0, size=(n, 6)), rng.uniform(0.0, 800.0, size=(n, 6))
    target = f["qpos"][rows, :N_ARM] + rng.normal(0.0, 0.1, size=(n, N_ARM))
    state = BatchedControllerState(rng.normal(0.0, 5.0, size=(n, 7)), rng.uniform(0, 800, size=(n, 6)),
                                   rng.normal(0.0, 5.0, size=(n, 6)))
    # the numpy law's inputs, read as the lockstep reads them from an MjData
    jac = np.zeros((n, 6, model.nv))
    quat = np.zeros((n, 4))
    for i in rows:
        data = batch.get_data(int(i))
        mujoco.mj_forward(batch.get_model(int(i)), data)  # a fresh MjData: kinematics as the step left them
        data.site_xpos[:] = f["site_xpos"][i]
        data.cdof[:] = f["cdof"][i]
        data.subtree_com[:] = f["subtree_com"][i]
        mujoco.mj_jacSite(model, data, jac[i, :3], jac[i, 3:], cfg.site_id)
        mujoco.mju_mat2Quat(quat[i], f["site_xmat"][i, cfg.site_id])
    expected, new_state = batched_impedance_control(
        cfg, jac[:, :, :N_ARM], f["site_xpos"][rows, cfg.site_id], quat, f["qpos"][rows, :N_ARM],
        f["qvel"][rows, :N_ARM], f["qfrc_bias"][rows, :N_ARM], ref_pos, ref_quat, cmd_wrench, cmd_stiffness, target, state)
    torque, stiffness, wrench = state.torque.copy(), state.stiffness.copy(), state.wrench.copy()
    ctrl = np.zeros_like(f["ctrl"])
    rates = np.array([cfg.stiffness_rate * cfg.dt, cfg.wrench_rate * cfg.dt, cfg.torque_step, cfg.pinv_damping,
                      cfg.nullspace_stiffness])
    impedance_rows(rows, kinematic_chain(model, cfg.site_body_id), cfg.site_id, int(model.body_rootid[cfg.site_body_id]),
                   f["cdof"], f["subtree_com"], f["site_xpos"], f["site_xmat"], f["qpos"], f["qvel"], f["qfrc_bias"],
                   ref_pos, ref_quat, cmd_wrench, cmd_stiffness, target, torque, stiffness, wrench,
                   np.asarray(cfg.torque_limit, float), rates, ctrl)
    np.testing.assert_array_equal(ctrl[rows, :N_ARM], expected)
    np.testing.assert_array_equal(torque, new_state.torque)
    np.testing.assert_array_equal(stiffness, new_state.stiffness)
    np.testing.assert_array_equal(wrench, new_state.wrench)
    assert np.ptp(expected) > 1.0  # torques that exercise the law, not its limits alone




@settings(max_examples=300, deadline=None)
@given(st.tuples(unit, unit, unit, unit).filter(lambda q: sum(x * x for x in q) > 1e-3))
def test_mat2quat_is_mujocos(q):
    q = np.array(q) / np.linalg.norm(q)
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, q)
    expected, got = np.zeros(4), np.zeros(4)
    mujoco.mju_mat2Quat(expected, mat)
    _mat2quat(mat, got)
    np.testing.assert_array_equal(got, expected)


ROUNDING = 1e-14  # positions within a metre, unit quaternions: a few float64 ulps


def references_one_by_one(bb, n, dt):
    """The references of ``n`` periods as written before they were compiled and cached: the
    motion's scalar arithmetic at every time, the spiral a Python loop of ``spiral_step``."""
    times = np.cumsum(np.concatenate([[bb.mg_time], np.full(n, dt)]))
    at = [bb.motion._at(min(t, bb.motion.duration)) for t in times[:-1]]
    pos, quat = np.array([p for p, _ in at]), np.array([q for _, q in at])
    theta, radius = bb.spiral_theta, bb.spiral_radius
    if bb.spiral_on:
        e1, e2 = bb.spiral_axes
        offsets = np.empty((n, 3))
        for k in range(n):
            offsets[k] = radius * (math.cos(theta) * e1 + math.sin(theta) * e2)
            theta, radius = spiral_step(theta, radius, *bb.spiral_params, dt)
        pos = pos + offsets
    return pos, quat, theta, radius, float(times[-1])


@settings(max_examples=200, deadline=None)
@given(**BLACKBOARD)
def test_a_ticks_references_are_those_of_the_uncompiled_uncached_code(start, goal_offset, turn, elapsed, spiral,
                                                                        theta, radius, spiral_params):
    bb = blackboard(start, goal_offset, turn, elapsed, spiral, theta, radius, spiral_params)
    pos, quat, theta, radius, time = references_one_by_one(bb, 50, 0.002)
    for _ in range(2):
        got_pos, got_quat = bb.copy().references(50, 0.002)
        # compiled: the same formulas, whose sines and square roots may round differently
        np.testing.assert_allclose(got_pos, pos, rtol=0, atol=ROUNDING)
        np.testing.assert_allclose(got_quat, quat, rtol=0, atol=ROUNDING)
    bb.references(50, 0.002)
    assert (bb.spiral_theta, bb.spiral_radius, bb.mg_time) == (theta, radius, time)
    for t in (elapsed, bb.motion.duration, bb.motion.duration + elapsed):  # at(): cached once ended
        for _ in range(2):
            got_pos, got_quat = bb.motion.at(t)
            want_pos, want_quat = bb.motion._at(min(t, bb.motion.duration))
            np.testing.assert_array_equal(got_pos, want_pos)
            np.testing.assert_array_equal(got_quat, want_quat)


def _reference_now(bb):
    """``reference()`` as computed without its kept value: the motion's scalar arithmetic."""
    pos, quat = bb.motion._at(min(bb.mg_time, bb.motion.duration))
    if bb.spiral_on:
        e1, e2 = bb.spiral_axes
        pos = pos + bb.spiral_radius * (math.cos(bb.spiral_theta) * e1 + math.sin(bb.spiral_theta) * e2)
    return pos, quat


@settings(max_examples=100, deadline=None)
@given(rows=st.lists(st.fixed_dictionaries(BLACKBOARD), min_size=1, max_size=4), change=st.sampled_from(
    ["nothing", "time", "motion", "spiral on/off", "spiral angle"]))
def test_the_reference_after_a_ticks_references_is_the_one_at_its_end_until_the_blackboard_changes(rows, change):
    # A tick's rewards and its next goals read ``reference()`` after the tick's references: the
    # value kept from the array evaluation must be the motion's at the end time to rounding,
    # for one blackboard's ``references`` and for many at once, and dropped once a field it
    # depends on changes.
    one = [blackboard(**r) for r in rows]
    many = [blackboard(**r) for r in rows]
    for bb in one:
        bb.references(50, 0.002)
    references_rows(many, 50, 0.002)
    for a, b in zip(one, many):
        for bb in (a, b):
            if change == "time":
                bb.mg_time += 0.002
            elif change == "motion":
                bb.motion = LinearMotion(bb.goal_pos, START_QUAT, bb.goal_pos + 0.01, START_QUAT)
            elif change == "spiral on/off":
                bb.spiral_on = not bb.spiral_on
            elif change == "spiral angle":
                bb.spiral_theta += 0.1
            got, want = bb.reference(), _reference_now(bb)
            np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-12)
            np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-12)
            if change != "nothing" and not (change == "spiral angle" and not bb.spiral_on):
                np.testing.assert_array_equal(got[0], want[0])  # computed again, not the kept value
                np.testing.assert_array_equal(got[1], want[1])
        np.testing.assert_array_equal(a.reference()[0], b.reference()[0])  # both ways keep the same value
        np.testing.assert_array_equal(a.reference()[1], b.reference()[1])


# a zero offset or turn too: a motion that does not move or does not turn (its fraction is 1)
motion_row = st.fixed_dictionaries({**BLACKBOARD,
                                    "goal_offset": st.one_of(st.just((0.0, 0.0, 0.0)), BLACKBOARD["goal_offset"]),
                                    "turn": st.one_of(st.just(START_QUAT), BLACKBOARD["turn"])})


@settings(max_examples=100, deadline=None)
@given(rows=st.lists(motion_row, min_size=1, max_size=6))
def test_the_references_of_many_blackboards_at_once_are_each_blackboards_own(rows):
    bbs = [blackboard(**r) for r in rows]
    want = [references_one_by_one(bb, 50, 0.002) for bb in bbs]
    pos, quat = references_rows(bbs, 50, 0.002)
    assert pos.shape == (50, len(bbs), 3) and quat.shape == (50, len(bbs), 4)
    for i, (bb, (w_pos, w_quat, theta, radius, time)) in enumerate(zip(bbs, want)):
        np.testing.assert_allclose(pos[:, i], w_pos, rtol=0, atol=ROUNDING)
        np.testing.assert_allclose(quat[:, i], w_quat, rtol=0, atol=ROUNDING)
        alone = blackboard(**rows[i]).references(50, 0.002)  # a row's values are its own
        np.testing.assert_array_equal(pos[:, i], alone[0])
        np.testing.assert_array_equal(quat[:, i], alone[1])
        assert (bb.spiral_theta, bb.spiral_radius, bb.mg_time) == (theta, radius, time)


status_row = st.fixed_dictionaries({**BLACKBOARD, "tool_offset": st.tuples(finite, finite, finite),
                                    "scale": st.sampled_from([1e-3, 0.01, 0.05]), "live": st.booleans(),
                                    "ticks": st.integers(0, 8)})


@settings(max_examples=100, deadline=None)
@given(rows=st.lists(status_row, min_size=1, max_size=6), threshold=st.sampled_from([0.005, 0.02, 0.1]),
       wait=st.integers(1, 6))
def test_every_leaf_status_over_many_blackboards_is_each_blackboards_own(rows, threshold, wait):
    # tools near their motions' goals, some within the threshold and some not
    bbs, tool_pos = [], []
    for r in rows:
        bb = blackboard(**{k: r[k] for k in BLACKBOARD})
        bb.leaf_ticks = [0, r["ticks"]]
        bbs.append(bb)
        tool_pos.append(bb.motion.goal_pos + r["scale"] * np.array(r["tool_offset"]))
    tool_pos, live = np.array(tool_pos), np.array([r["live"] for r in rows])
    board = board_of(bbs)
    for status in (Always(Status.SUCCESS), Always(Status.RUNNING), Reached(threshold), Waited(1, wait)):
        got = status.rows(board, np.arange(len(bbs)), tool_pos, live)
        assert got.shape == (len(bbs),)
        assert got.tolist() == [int(status(bb, p, bool(lv))) for bb, p, lv in zip(bbs, tool_pos, live)]


@settings(max_examples=100, deadline=None)
@given(rows=st.lists(motion_row, min_size=1, max_size=5), ticks=st.integers(1, 3), pick=st.integers(0, 4))
def test_the_rows_boards_references_are_each_blackboards_own(rows, ticks, pick):
    # The batch's blackboards as arrays: a tick's references, the spirals advanced, and the
    # reference read afterwards (kept, or computed again once a motion starts) for a subset of
    # rows, bit for bit what each row's own blackboard gives.
    bbs = [blackboard(**r) for r in rows]
    board = board_of(bbs)
    chosen = np.arange(len(bbs))[pick % len(bbs):]
    for _ in range(ticks):
        pos, quat = board.references(chosen, 50, 0.002)
        for j, r in enumerate(chosen):
            want_pos, want_quat = bbs[r].references(50, 0.002)
            np.testing.assert_array_equal(pos[:, j], want_pos)
            np.testing.assert_array_equal(quat[:, j], want_quat)
            assert (board.spiral_theta[r], board.spiral_radius[r], board.mg_time[r]) == (
                bbs[r].spiral_theta, bbs[r].spiral_radius, bbs[r].mg_time)
        got_pos, got_quat = board.reference(chosen)
        for j, r in enumerate(chosen):
            np.testing.assert_array_equal(got_pos[j], bbs[r].reference()[0])
            np.testing.assert_array_equal(got_quat[j], bbs[r].reference()[1])
    r = int(chosen[0])  # a motion starting: the reference is the scalar one again
    board.goal_pos[r] = bbs[r].goal_pos = bbs[r].goal_pos + 0.01
    board.start_motion(r)
    pos, quat = bbs[r].reference()
    bbs[r].motion, bbs[r].mg_time = LinearMotion(pos, quat, bbs[r].goal_pos, bbs[r].goal_quat), 0.0
    np.testing.assert_array_equal(board.motion_rows[r], bbs[r].motion.row)
    got_pos, got_quat = board.reference(np.array([r]))
    np.testing.assert_array_equal(got_pos[0], bbs[r].reference()[0])
    np.testing.assert_array_equal(got_quat[0], bbs[r].reference()[1])
