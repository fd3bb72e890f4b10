"""Reward terms against hand computations (paper section "Reward Functions"), evaluated as each
engine evaluates them: in JAX (the compiled engine) and on the host (the native engine)."""

import math

import numpy as np
import pytest

import mjxskill  # noqa: F401
from mjxskill.engine.common.arrays import HOST, JAX
from mjxskill.engine.common.rewards import Observation, _raw_term, build_terms, exp_reward
from mjxskill.engine.common.types import objective_matrix
from mjxskill.scenario import load_scenario
from mjxskill.scenario.schema import Reward

# Two bound objects: slot 0 an object at (1, 0, 0) turned 90 deg about z, slot 1 a target at
# the origin with identity orientation.
SLOT_OF = {"obj": 0, "tgt": 1}
QUAT_Z90 = [math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)]


@pytest.fixture(params=[JAX, HOST], ids=["jax", "host"])
def xp(request):
    return request.param


def obs(xp, **overrides) -> Observation:
    fields = dict(
        tool_pos=xp.asarray([0.3, 0.4, 0.0]),  # 0.5 m from the target
        tool_quat=xp.asarray([1.0, 0.0, 0.0, 0.0]),
        ref_pos=xp.asarray([0.3, 0.4, 0.12]),  # 0.12 m from the tool
        slot_pos=xp.asarray([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
        slot_quat=xp.asarray([QUAT_Z90, [1.0, 0.0, 0.0, 0.0]]),
        wrench=xp.asarray([1.0, -2.0, -7.0, 5.0, 5.0, 5.0]),
        bt_succeeded=xp.asarray(True),
        contact_force=xp.asarray(0.0),  # N: the tool touches nothing
    )
    fields.update(overrides)
    return Observation(**fields)


def raw(xp, kind, constants=None, **fields):
    """(raw function, largest raw value, smallest raw value)."""
    reward = Reward(name="r", kind=kind, weight=1.0, objective="o", constants=constants or {}, **fields)
    fn, smallest, largest = _raw_term(reward, SLOT_OF, xp)
    return fn, largest, smallest


def test_task_completion_pays_only_after_success(xp):
    fn, largest, smallest = raw(xp, "task_completion", {"value": 8.0})
    assert float(fn(obs(xp))) == 8.0
    assert float(fn(obs(xp, bt_succeeded=xp.asarray(False)))) == 0.0
    assert (largest, smallest) == (8.0, 0.0)


def test_ee_distance_to_box_is_inverse_distance(xp):
    fn, best, _ = raw(xp, "ee_distance_to_box", {"w": 2.0, "d_o": 0.006}, target="tgt")
    assert float(fn(obs(xp))) == pytest.approx(1.0 / (2.0 * (0.5 + 0.006)), rel=1e-6)
    assert best == pytest.approx(1.0 / (2.0 * 0.006))


def test_target_offset_moves_the_target_point(xp):
    # The offset target sits 0.25 m above the tool.
    fn, largest, _ = raw(xp, "ee_distance_to_box", {"w": 1.0, "d_o": 0.0}, target="tgt", target_offset=np.array([0.3, 0.4, 0.25]))
    assert float(fn(obs(xp))) == pytest.approx(4.0, rel=1e-6)
    assert math.isinf(largest)  # no offset: unbounded as the tool reaches the target


def test_applied_wrench_sums_absolute_forces_and_is_capped(xp):
    fn, largest, smallest = raw(xp, "applied_wrench", {"cap": 100.0})
    assert float(fn(obs(xp))) == pytest.approx(1.0 + 2.0 + 7.0)  # torques are not forces
    assert float(fn(obs(xp, wrench=xp.asarray([1e6, 0, 0, 0, 0, 0.0])))) == 100.0
    assert (largest, smallest) == (100.0, 0.0)


def test_exponential_rewards_follow_the_paper_formula(xp):
    sigma, d_o = 0.4, 0.01
    fn, best, _ = raw(xp, "exp_ee_to_goal", {"sigma_w": sigma, "d_o": d_o}, target="tgt")
    assert float(fn(obs(xp))) == pytest.approx(math.exp(-(0.5 + d_o) / (2 * sigma**2)), rel=1e-6)
    assert best == pytest.approx(math.exp(-d_o / (2 * sigma**2)))
    fn, _, _ = raw(xp, "exp_ee_to_reference", {"sigma_w": sigma, "d_o": 0.0})
    assert float(fn(obs(xp))) == pytest.approx(math.exp(-0.12 / (2 * sigma**2)), rel=1e-6)


def test_object_pose_divergence_weights_position_and_angle(xp):
    fn, best, _ = raw(
        xp, "object_pose_divergence",
        {"sigma_w": 0.4, "d_o": 0.0, "position_weight": 6.0, "orientation_weight": 2.0},
        object="obj",
        target="tgt",
    )
    expected = 6.0 * math.exp(-1.0 / 0.32) + 2.0 * math.exp(-(math.pi / 2) / 0.32)
    assert float(fn(obs(xp))) == pytest.approx(expected, rel=1e-5)
    assert best == pytest.approx(8.0)


def test_exp_reward_is_one_at_zero_distance(xp):
    assert float(exp_reward(0.0, 0.4, 0.0, xp)) == 1.0


def test_unknown_kind_names_the_reward(xp):
    with pytest.raises(ValueError, match="reward 'r'.*unknown kind 'bogus'"):
        raw(xp, "bogus")


def test_scenario_terms_map_to_objectives_with_their_weights():
    scn = load_scenario("peg")
    slots = {name: i for i, name in enumerate(["BoxWithHole-1", "Peg-1"])}
    terms = build_terms(scn, slots, JAX)
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
