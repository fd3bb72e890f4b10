"""Reward terms against hand computations (paper section "Reward Functions")."""

import math
from types import SimpleNamespace

import jax.numpy as jnp
import numpy as np
import pytest

import mjxskill  # noqa: F401
from mjxskill.engine.mjx.rewards import Observation, _raw_term, build_terms, exp_reward
from mjxskill.engine.common.types import objective_matrix
from mjxskill.scenario import load_scenario
from mjxskill.scenario.schema import Reward

# Two bound objects: slot 0 an object at (1, 0, 0) turned 90 deg about z, slot 1 a target at
# the origin with identity orientation.
BINDINGS = SimpleNamespace(slot_of={"obj": 0, "tgt": 1})
QUAT_Z90 = [math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)]


def obs(**overrides) -> Observation:
    fields = dict(
        tool_pos=jnp.array([0.3, 0.4, 0.0]),  # 0.5 m from the target
        tool_quat=jnp.array([1.0, 0.0, 0.0, 0.0]),
        ref_pos=jnp.array([0.3, 0.4, 0.12]),  # 0.12 m from the tool
        slot_pos=jnp.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
        slot_quat=jnp.array([QUAT_Z90, [1.0, 0.0, 0.0, 0.0]]),
        wrench=jnp.array([1.0, -2.0, -7.0, 5.0, 5.0, 5.0]),
        bt_succeeded=jnp.array(True),
        contact_force=jnp.array(0.0),  # N: the tool touches nothing
    )
    fields.update(overrides)
    return Observation(**fields)


def raw(kind, constants=None, **fields):
    """(raw function, largest raw value, smallest raw value)."""
    reward = Reward(name="r", kind=kind, weight=1.0, objective="o", constants=constants or {}, **fields)
    fn, smallest, largest = _raw_term(reward, BINDINGS)
    return fn, largest, smallest


def test_task_completion_pays_only_after_success():
    fn, largest, smallest = raw("task_completion", {"value": 8.0})
    assert float(fn(obs())) == 8.0
    assert float(fn(obs(bt_succeeded=jnp.array(False)))) == 0.0
    assert (largest, smallest) == (8.0, 0.0)


def test_ee_distance_to_box_is_inverse_distance():
    fn, best, _ = raw("ee_distance_to_box", {"w": 2.0, "d_o": 0.006}, target="tgt")
    assert float(fn(obs())) == pytest.approx(1.0 / (2.0 * (0.5 + 0.006)), rel=1e-6)
    assert best == pytest.approx(1.0 / (2.0 * 0.006))


def test_target_offset_moves_the_target_point():
    # The offset target sits 0.25 m above the tool.
    fn, largest, _ = raw("ee_distance_to_box", {"w": 1.0, "d_o": 0.0}, target="tgt", target_offset=np.array([0.3, 0.4, 0.25]))
    assert float(fn(obs())) == pytest.approx(4.0, rel=1e-6)
    assert math.isinf(largest)  # no offset: unbounded as the tool reaches the target


def test_applied_wrench_sums_absolute_forces_and_is_capped():
    fn, largest, smallest = raw("applied_wrench", {"cap": 100.0})
    assert float(fn(obs())) == pytest.approx(1.0 + 2.0 + 7.0)  # torques are not forces
    assert float(fn(obs(wrench=jnp.array([1e6, 0, 0, 0, 0, 0.0])))) == 100.0
    assert (largest, smallest) == (100.0, 0.0)


def test_exponential_rewards_follow_the_paper_formula():
    sigma, d_o = 0.4, 0.01
    fn, best, _ = raw("exp_ee_to_goal", {"sigma_w": sigma, "d_o": d_o}, target="tgt")
    assert float(fn(obs())) == pytest.approx(math.exp(-(0.5 + d_o) / (2 * sigma**2)), rel=1e-6)
    assert best == pytest.approx(math.exp(-d_o / (2 * sigma**2)))
    fn, _, _ = raw("exp_ee_to_reference", {"sigma_w": sigma, "d_o": 0.0})
    assert float(fn(obs())) == pytest.approx(math.exp(-0.12 / (2 * sigma**2)), rel=1e-6)


def test_object_pose_divergence_weights_position_and_angle():
    fn, best, _ = raw(
        "object_pose_divergence",
        {"sigma_w": 0.4, "d_o": 0.0, "position_weight": 6.0, "orientation_weight": 2.0},
        object="obj",
        target="tgt",
    )
    expected = 6.0 * math.exp(-1.0 / 0.32) + 2.0 * math.exp(-(math.pi / 2) / 0.32)
    assert float(fn(obs())) == pytest.approx(expected, rel=1e-5)
    assert best == pytest.approx(8.0)


def test_exp_reward_is_one_at_zero_distance():
    assert float(exp_reward(0.0, 0.4, 0.0)) == 1.0


def test_unknown_kind_names_the_reward():
    with pytest.raises(ValueError, match="reward 'r'.*unknown kind 'bogus'"):
        raw("bogus")


def test_scenario_terms_map_to_objectives_with_their_weights():
    scn = load_scenario("peg")
    slots = {name: i for i, name in enumerate(["BoxWithHole-1", "Peg-1"])}
    terms = build_terms(scn, SimpleNamespace(slot_of=slots))
    m = objective_matrix(terms, len(scn.objective_names))
    for r, reward in enumerate(scn.rewards):
        col = scn.objective_names.index(reward.objective)
        assert m[r, col] == pytest.approx(reward.weight)
        assert np.count_nonzero(m[r]) == (1 if reward.weight else 0)
    # A diverged world is charged the worst weighted value: the cap for the (negative-weight)
    # wrench cost, zero for the positive rewards.
    by_name = {t.name: t for t in terms}
    assert by_name["applied_wrench"].worst_raw == 100.0
    assert by_name["bt_success"].worst_raw == 0.0
