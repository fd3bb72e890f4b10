"""The JAX impedance controller against its numpy/native-MuJoCo twin, the
quaternion helpers against MuJoCo's mju_* functions, and the rate limits against their closed
forms."""

from __future__ import annotations

import mjxskill  # noqa: F401  (XLA flags before jax runs)
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mujoco import mjx

from mjxskill.sim import load_scene
from mjxskill.engine.mjx.controller import (
    COMMAND_SIZE, ControllerConfig, ControllerState, impedance_control, make_command, split_command)
from mjxskill.engine.native.controller import NativeControllerState, native_impedance_control
from mjxskill.engine.common.rotations import quat_conj, quat_mul, quat_to_rotvec, rotvec_to_quat

N_STATES = 100


def _random_case(model, data, cfg, rng):
    """A random arm state near a reachable pose, with a command and a previous controller state."""
    lo, hi = model.jnt_range[:7, 0], model.jnt_range[:7, 1]
    data.qpos[:7] = rng.uniform(0.8 * lo, 0.8 * hi)
    data.qvel[:7] = rng.normal(scale=0.5, size=7)
    mujoco.mj_forward(model, data)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, data.site_xmat[cfg.site_id])
    turn = rng.normal(size=3) * 0.3
    ref_quat = np.zeros(4)
    mujoco.mju_mulQuat(ref_quat, np.asarray(rotvec_to_quat(jnp.asarray(turn))), quat)
    command = np.concatenate([data.site_xpos[cfg.site_id] + rng.normal(scale=0.02, size=3), ref_quat,
                              rng.normal(scale=5.0, size=6), rng.uniform(0.0, 800.0, 6)])
    nullspace_target = rng.uniform(0.8 * lo, 0.8 * hi)
    previous = (data.qfrc_bias[:7] + rng.normal(scale=1.0, size=7),
                command[13:19] + rng.normal(scale=2.0, size=6), command[7:13] + rng.normal(scale=0.05, size=6))
    return command, nullspace_target, previous


@pytest.mark.parametrize("limited", [True, False], ids=["rate_limited", "unlimited"])
def test_jax_controller_matches_native_numpy_controller_on_100_states(limited):
    """float64 on both sides; 'unlimited' lifts rate limits and saturation so that the whole law
    (not the clipping) is compared."""
    model = load_scene("push")
    overrides = {} if limited else dict(torque_step=1e9, stiffness_rate=1e9, wrench_rate=1e9)
    cfg = ControllerConfig.from_model(model, **overrides)
    if not limited:
        cfg = cfg._replace(torque_limit=(1e9,) * 7)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    rng = np.random.default_rng(42)
    with jax.enable_x64(True):
        mx = mjx.put_model(model)
        control = jax.jit(lambda d, c, n, s: impedance_control(cfg, mx, d, c, n, s))
        worst = 0.0
        for _ in range(N_STATES):
            command, target, previous = _random_case(model, data, cfg, rng)
            tau_ref, state_ref = native_impedance_control(cfg, model, data, command, target,
                                                          NativeControllerState(*previous))
            dx = mjx.put_data(model, data)
            assert dx.qpos.dtype == jnp.float64
            tau, state = control(dx, jnp.asarray(command), jnp.asarray(target),
                                 ControllerState(*map(jnp.asarray, previous)))
            tau = np.asarray(tau)
            worst = max(worst, np.max(np.abs(tau - tau_ref)) / np.max(np.abs(tau_ref)))
            np.testing.assert_allclose(np.asarray(state.stiffness), state_ref.stiffness, rtol=1e-12)
            np.testing.assert_allclose(np.asarray(state.wrench), state_ref.wrench, rtol=1e-12)
    assert worst < 1e-6, f"largest relative torque difference {worst:.2e}"


def test_rate_limits_and_saturation_follow_their_closed_forms():
    model = load_scene("push")
    cfg = ControllerConfig.from_model(model)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    dx = mjx.put_data(model, data)
    far = make_command(jnp.asarray(data.site_xpos[cfg.site_id]) + 0.5, jnp.array([1.0, 0, 0, 0]),
                       wrench=jnp.full(6, 30.0), stiffness=jnp.full(6, 900.0))
    prev = ControllerState(jnp.asarray(data.qfrc_bias[:7], jnp.float32), jnp.full(6, 100.0), jnp.zeros(6))
    tau, state = impedance_control(cfg, mjx.put_model(model), dx, far, jnp.zeros(7), prev)
    np.testing.assert_allclose(state.stiffness, 100.0 + 500.0 * cfg.dt, rtol=1e-6)  # 500 /s
    np.testing.assert_allclose(state.wrench, 10.0 * cfg.dt, rtol=1e-6)  # 10 N/s
    step = np.abs(np.asarray(tau) - data.qfrc_bias[:7])
    assert np.all(step <= cfg.torque_step + 1e-4) and np.any(step > cfg.torque_step - 1e-4)
    # Saturation: a previous torque beyond the limit is brought back to it.
    over = ControllerState(jnp.asarray(cfg.torque_limit) * 1.5, prev.stiffness, prev.wrench)
    tau, _ = impedance_control(cfg, mjx.put_model(model), dx, far, jnp.zeros(7), over)
    np.testing.assert_allclose(np.abs(np.asarray(tau)), cfg.torque_limit, rtol=1e-6)


def test_config_reads_torque_limits_from_the_model():
    cfg = ControllerConfig.from_model(load_scene("peg"))
    assert cfg.torque_limit == (320.0, 320.0, 176.0, 176.0, 110.0, 40.0, 40.0)
    assert cfg.dt == 0.002 and cfg.nullspace_stiffness == 5.0


@pytest.mark.parametrize("damping", [0.0, -1e-6, float("nan")])
def test_config_refuses_a_pseudo_inverse_damping_that_is_not_positive(damping):
    # the compiled law's Cholesky pivots are at least its square root: zero would divide by zero
    with pytest.raises(ValueError, match="pinv_damping"):
        ControllerConfig.from_model(load_scene("peg"), pinv_damping=damping)


def test_command_packs_and_unpacks():
    command = make_command(jnp.arange(3.0), jnp.array([1.0, 0, 0, 0]), jnp.arange(6.0), jnp.arange(6.0) + 10)
    assert command.shape == (COMMAND_SIZE,)
    parts = split_command(command)
    np.testing.assert_array_equal(parts.pos, [0, 1, 2])
    np.testing.assert_array_equal(parts.stiffness, np.arange(6.0) + 10)
    default = split_command(make_command(jnp.zeros((5, 3)), jnp.tile(jnp.array([1.0, 0, 0, 0]), (5, 1))))
    np.testing.assert_array_equal(default.stiffness[0], [400, 400, 400, 50, 50, 50])
    with pytest.raises(ValueError, match="last dimension 19"):
        split_command(jnp.zeros(18))
    with pytest.raises(ValueError, match="sizes"):
        make_command(jnp.zeros(3), jnp.zeros(3))


unit_quats = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
    lambda v: np.linalg.norm(v) > 0.1).map(lambda v: np.asarray(v) / np.linalg.norm(v))


@settings(max_examples=40, deadline=None)
@given(unit_quats, unit_quats)
def test_quaternion_helpers_match_mujoco(a, b):
    expected = np.zeros(4)
    mujoco.mju_mulQuat(expected, a, b)
    np.testing.assert_allclose(quat_mul(jnp.asarray(a), jnp.asarray(b)), expected, atol=1e-6)
    neg = np.zeros(4)
    mujoco.mju_negQuat(neg, a)
    np.testing.assert_allclose(quat_conj(jnp.asarray(a)), neg, atol=1e-7)
    rotvec = np.zeros(3)
    mujoco.mju_quat2Vel(rotvec, a, 1.0)
    ours = np.asarray(quat_to_rotvec(jnp.asarray(a)))
    if abs(np.linalg.norm(rotvec) - np.pi) < 1e-4:
        # A half turn about n is also one about -n: the sign of the axis is a free choice there
        # (hypothesis found w = -3e-36, where the two pick opposite ones).
        assert min(np.abs(ours - rotvec).max(), np.abs(ours + rotvec).max()) < 2e-5
    else:
        np.testing.assert_allclose(ours, rotvec, atol=2e-5)
    back = np.asarray(rotvec_to_quat(jnp.asarray(rotvec)))
    assert min(np.abs(back - a).max(), np.abs(back + a).max()) < 2e-5


@pytest.mark.parametrize("strategy,chunk", [("map", None), ("chunked", 2)])
def test_batching_strategies_agree_with_vmap(strategy, chunk):
    """Every strategy maps the same per-world function; zero-size leaves like MJX's are kept."""
    from mjxskill.engine.mjx.batching import over_worlds

    def per_world(x, tree):
        return {"y": jnp.sin(x) * tree["a"].sum(), "empty": tree["empty"] + 1.0}

    x = jnp.arange(6.0)
    tree = {"a": jnp.arange(18.0).reshape(6, 3), "empty": jnp.zeros((6, 0))}
    expected = jax.vmap(per_world)(x, tree)
    got = jax.jit(over_worlds(per_world, strategy, chunk))(x, tree)
    np.testing.assert_allclose(got["y"], expected["y"], rtol=1e-6)
    assert got["empty"].shape == (6, 0)
    with pytest.raises(ValueError, match="unknown batching strategy 'pmap'"):
        over_worlds(per_world, "pmap")
    with pytest.raises(ValueError, match="do not split"):
        over_worlds(per_world, "chunked", 4)(x, tree)
