"""The native engine's control callback (``mjxskill.engine.native.callback``), on its own: where it
reads an ``mjData``, what it leaves alone, and what one tick of it computes against the law run
between single steps (the per-step loop it replaced). Whole episodes through it equal the numpy
lockstep's bit for bit: tests/engine/native/test_batched.py.
"""

import ctypes

import mujoco
import numpy as np
import pytest
from mujoco.batch import Batch

from mjxskill import load_scenario
from mjxskill.engine.native import NativeRollout
from mjxskill.engine.native.batched import BOUND, kinematic_chain
from mjxskill.engine.native.callback import FIELDS, ControlContext, control_callback, data_offsets, installed
from mjxskill.engine.native.kernels import add_forces, impedance_rows
from mjxskill.errors import ScenarioError
from mjxskill.sim.model import CONTROL_USERDATA, build_model


@pytest.fixture(scope="module")
def peg():
    return NativeRollout(load_scenario("peg"), worlds=1, episode_seconds=1.0)


def word(data, offset: int) -> int:
    return ctypes.c_int64.from_address(data._address + 8 * offset).value


@pytest.mark.parametrize("scenario", ["push", "peg"])
def test_the_offsets_hold_each_fields_address_in_any_data_of_the_model(scenario):
    model = build_model(load_scenario(scenario))
    offsets = data_offsets(model)
    assert len(set(offsets)) == len(FIELDS)  # every field non-empty here: no two share a place
    for data in (mujoco.MjData(model), mujoco.MjData(model)):
        for name, offset in zip(FIELDS, offsets):
            assert word(data, offset) == getattr(data, name).ctypes.data, name


def test_every_scenario_model_ends_with_the_callbacks_userdata():
    for scenario in ("push", "peg"):
        assert build_model(load_scenario(scenario)).nuserdata >= CONTROL_USERDATA


def test_installed_restores_the_callback_before_it(peg):
    def mine(model, data):
        pass
    mujoco.set_mjcb_control(mine)
    try:
        with installed(control_callback(peg.mj_model, peg.data_offsets)):
            assert mujoco.get_mjcb_control() is not mine
        assert mujoco.get_mjcb_control() is mine
    finally:
        mujoco.set_mjcb_control(None)


def test_data_without_a_context_steps_as_with_no_callback(peg):
    model = peg.mj_model
    plain, called = mujoco.MjData(model), mujoco.MjData(model)
    for data in (plain, called):
        data.ctrl[:] = 3.0
    for _ in range(20):
        mujoco.mj_step(model, plain)
    with installed(control_callback(model, peg.data_offsets)):
        for _ in range(20):
            mujoco.mj_step(model, called)
    assert np.array_equal(plain.qpos, called.qpos) and np.array_equal(called.ctrl, plain.ctrl)


def one_tick(peg, how: str, bad_row: int | None = None) -> list[np.ndarray]:
    """One tick of 50 steps for four rows from different arm postures, ``how``: "single steps"
    (``impedance_rows`` between single ``Batch.step`` calls, the per-step loop) or "callback"
    (one ``Batch.step`` of 50, the law inside); ``bad_row``'s velocities NaN at the start (MuJoCo
    resets that row at its first step). Returns the rows' qpos, qvel, ctrl, time, law state and
    touch force sums."""
    model, cfg, steps, n = peg.mj_model, peg.setup.ctrl, 50, 4
    chain, root, site = kinematic_chain(model, cfg.site_body_id), int(model.body_rootid[cfg.site_body_id]), cfg.site_id
    rng = np.random.default_rng(0)
    start = np.tile(model.qpos0, (n, 1))
    start[:, :7] += rng.normal(0.0, 0.2, (n, 7))
    ref_pos = rng.normal(0.0, 0.01, (steps, n, 3))
    ref_quat = np.tile([0.0, 1.0, 0.0, 0.0], (steps, n, 1))
    cmd_wrench, cmd_stiffness = rng.normal(0.0, 5.0, (n, 6)), np.tile([800.0] * 3 + [80.0] * 3, (n, 1))
    limits = np.array([cfg.stiffness_rate * cfg.dt, cfg.wrench_rate * cfg.dt, cfg.torque_step, cfg.pinv_damping,
                       cfg.nullspace_stiffness])
    sensors = np.asarray(peg.setup.bindings.force_sensors, np.int64)
    batch = Batch(model, n, nthread=1)
    f = {name: batch.bind(name) for name in BOUND}
    batch.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
    f["qpos"][:], f["time"][:] = start, 1.0  # a clock MuJoCo's reset (to 0) shows in
    batch.forward()
    refs = f["site_xpos"][:, site] + ref_pos
    torque, stiffness = np.array(f["qfrc_bias"][:, :7]), np.array(cmd_stiffness)
    wrench, target, rows = np.zeros((n, 6)), np.array(start[:, :7]), np.arange(n)
    if how == "single steps":
        force_sum, force_peak = np.zeros(n), np.zeros(n)
        for k in range(steps):
            impedance_rows(rows, chain, site, root, f["cdof"], f["subtree_com"], f["site_xpos"], f["site_xmat"],
                           f["qpos"], f["qvel"], f["qfrc_bias"], refs[k], ref_quat[k], cmd_wrench, cmd_stiffness,
                           target, torque, stiffness, wrench, np.asarray(cfg.torque_limit, float), limits, f["ctrl"])
            batch.step()
            add_forces(rows, f["sensordata"], sensors, force_sum, force_peak)
    else:
        context = ControlContext(peg.data_offsets, steps, cfg, chain, root, sensors, torque, stiffness, wrench, target)
        context.bind(f["userdata"], f)
        context.begin_tick(rows, refs, ref_quat, cmd_wrench, cmd_stiffness)
        if bad_row is not None:
            f["qvel"][bad_row] = np.nan
        with installed(control_callback(model, peg.data_offsets)):
            batch.step(nstep=steps)
        force_sum, force_peak = context.end_tick(rows, f["sensordata"])
    return [np.array(x) for x in (f["qpos"], f["qvel"], f["ctrl"], f["time"], torque, stiffness, wrench, force_sum,
                                  force_peak, f["userdata"][:, -CONTROL_USERDATA])]


def test_a_tick_in_one_call_equals_the_law_between_single_steps(peg):
    """The callback's one ``Batch.step`` of 50 against 50 single steps with the law between them:
    the same states, torques, law state and touch force sums, bit for bit."""
    single, called = one_tick(peg, "single steps"), one_tick(peg, "callback")
    for a, b in zip(single[:-1], called[:-1]):  # all but the userdata, which only the callback's batch binds
        np.testing.assert_array_equal(a, b)
    assert np.ptp(called[0][:, :7], axis=0).max() > 0.1  # the rows moved apart: each read its own row


def test_a_row_mujoco_resets_in_a_tick_leaves_the_others_alone(peg):
    """A row whose state goes bad is reset by MuJoCo (its clock restarts, its ``userdata`` is
    zero again, so the callback leaves it); the other rows end the tick as without it."""
    clean, broken = one_tick(peg, "callback"), one_tick(peg, "callback", bad_row=2)
    others = [0, 1, 3]
    for a, b in zip(clean, broken):
        np.testing.assert_array_equal(a[others], b[others])
    time, context = broken[3], broken[-1]
    assert time[2] < time[0] == time[1] == time[3]  # the engine's clock test marks it diverged
    assert context[2] == 0 and (context[others] != 0).all()  # and so does its userdata, even at an episode's start


@pytest.mark.parametrize("userdata", [0, 2])
def test_another_models_data_stepped_meanwhile_is_left_alone(peg, userdata):
    """While a batch's callback is installed, data of another model (activations, so its arrays
    sit elsewhere; no userdata, or userdata holding numbers that name no live context) steps as
    with no callback."""
    xml = f"""<mujoco><size nuserdata="{userdata}"/><worldbody><body><joint name="j"/><geom size=".1" mass="1"/>
              </body></worldbody><actuator><general joint="j" dyntype="filter" dynprm="0.05"/></actuator></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    plain, called = mujoco.MjData(model), mujoco.MjData(model)
    for data in (plain, called):
        data.ctrl[:], data.userdata[:] = 0.7, 12345.0
    for _ in range(50):
        mujoco.mj_step(model, plain)
    with installed(control_callback(peg.mj_model, peg.data_offsets)):
        for _ in range(50):
            mujoco.mj_step(model, called)
    assert np.array_equal(plain.qpos, called.qpos) and np.array_equal(plain.act, called.act)


def test_a_model_integrated_with_rk4_is_refused_by_name():
    scn = load_scenario("push")
    model = build_model(scn)
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    with pytest.raises(ScenarioError, match="integrator RK4"):
        NativeRollout(scn, mj_model=model)
