"""The measured interaction force: the normal contact force between the tool
and everything else, from MuJoCo's touch sensors that build_model puts around the tool
(mjxskill.sim.tool_force). References: MuJoCo's mj_contactForce, a resting weight (m g) and the
episode's own bookkeeping (the reward's total is the mean force times the ticks)."""

import jax
import mujoco
import numpy as np
import pytest

from mjxskill import build_model, load_scenario
from mjxskill.engine.native import NativeRollout
from mjxskill.sim.tool_force import tool_force_addresses
from mjxskill.task import plan_task
from scenario_texts import shipped_text, write_copy


def _tool_contact_force(model, data) -> float:
    """Sum over the contacts touching the tool's geom of MuJoCo's normal contact force."""
    tool = model.geom("tool_geom").id
    total, force = 0.0, np.zeros(6)
    for i in range(data.ncon):
        if tool in (data.contact[i].geom1, data.contact[i].geom2):
            mujoco.mj_contactForce(model, data, i, force)
            total += force[0]
    return total


def test_the_sensors_sum_mj_contact_force_and_carry_a_resting_weight():
    # The arm straight up (the pusher's face up) holds the 2.5 kg prism resting on it, centre of
    # mass above the face's centre; a stiff joint hold keeps the arm where it is. The goal
    # corner's fence and stop are half-spaces: its frame goes where the arm is on their inside.
    scn = load_scenario("push")
    model = build_model(scn)
    data = mujoco.MjData(model)
    data.mocap_pos[model.body("goal").mocapid[0]] = (-10.0, 10.0, 0.035)
    mujoco.mj_kinematics(model, data)
    face = data.site_xpos[model.site("tool").id].copy()  # the pusher's top at q = 0
    prism = model.body("object").id
    com = model.body_ipos[prism]
    data.qpos[7:10] = face + [-com[0], -com[1], 0.035 - 1e-4]
    data.qpos[10:14] = [1, 0, 0, 0]
    sensors = list(tool_force_addresses(model))
    assert len(sensors) == 1
    readings = []
    for _ in range(1500):
        mujoco.mj_forward(model, data)
        data.ctrl[:7] = data.qfrc_bias[:7] - 2000.0 * data.qpos[:7] - 50.0 * data.qvel[:7]
        mujoco.mj_step(model, data)
        readings.append(float(data.sensordata[sensors].sum()))
        if len(readings) % 300 == 0:  # MuJoCo's own contact forces of the same state
            mujoco.mj_forward(model, data)
            assert data.sensordata[sensors].sum() == pytest.approx(_tool_contact_force(model, data), rel=1e-12, abs=1e-12)
    weight = model.body_mass[prism] * np.linalg.norm(model.opt.gravity)
    assert np.mean(readings[-250:]) == pytest.approx(weight, rel=0.01)
    assert np.linalg.norm(data.qpos[7:9] - (face[:2] - com[:2])) < 2e-3  # it stayed resting on the face


def test_no_contact_no_force_and_the_reward_is_the_mean_force_per_tick(tmp_path):
    # The peg's first half second is the approach in free space: nothing touches the tool.
    peg = load_scenario("peg")
    free = NativeRollout(peg, plan_task(peg), worlds=2, episode_seconds=0.5)
    out = free(np.array([[-5.0, 0.0, 0.0]]), jax.random.key(0))
    assert np.all(out.metrics["peak_contact_force"] == 0) and np.all(out.metrics["mean_contact_force"] == 0)
    # The push presses the prism: a contact_force reward totals the mean force of each tick.
    text = shipped_text("push").replace(
        "  - {name: reference_tracking,",
        "  - {name: gentle, kind: contact_force, objective: applied_force, weight: -1.0, constants: {cap: 1000.0}}\n"
        "  - {name: reference_tracking,")
    push = load_scenario(write_copy(tmp_path, "push", text))
    engine = NativeRollout(push, plan_task(push), worlds=2, episode_seconds=6.0)
    out = engine(np.array([[-0.05, -0.15, 0.07, -0.10]]), jax.random.key(1))
    mean, peak = out.metrics["mean_contact_force"][0], out.metrics["peak_contact_force"][0]
    assert np.all(mean > 0.5) and np.all(peak > mean)
    np.testing.assert_allclose(out.metrics["reward_gentle"][0], mean * engine.setup.ticks, rtol=1e-9)
