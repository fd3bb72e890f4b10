"""The benchmark problems' whole-front hypervolumes (benchmarks/mobo_quality.py), which the
regret about a run's own reference point divides by: against the exact hypervolume code, a
closed form and Monte Carlo."""

import os
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
from capabilities import require  # noqa: E402
import mobo_quality as mq  # noqa: E402

from mjxskill.gp import hypervolume  # noqa: E402
from mjxskill.gp.pareto import pareto_mask  # noqa: E402

refs_2d = st.tuples(st.floats(0.05, 3.0), st.floats(0.05, 3.0))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 40))
def test_staircase_hypervolume_is_the_exact_one(seed, n):
    rng = np.random.default_rng(seed)
    y, ref = rng.random((n, 2)), rng.uniform(0.2, 1.2, 2)
    assert mq._staircase_hypervolume(y, ref) == pytest.approx(hypervolume(y, ref), rel=1e-12, abs=1e-12)


@settings(max_examples=25, deadline=None)
@given(ref=refs_2d)
def test_zdt1_closed_form_against_a_dense_front(ref):
    f1 = np.linspace(0.0, 1.0, 20001)
    front = np.stack([f1, 1.0 - np.sqrt(f1)], axis=1)
    sampled = mq._staircase_hypervolume(front, np.asarray(ref))
    exact = mq.zdt1_front_hypervolume(ref)
    assert sampled <= exact + 1e-12  # a finite sample of the front dominates less
    assert exact - sampled < 1e-3 * max(ref[1], 1.0)


def test_zdt1_about_the_problem_reference_is_its_known_maximum():
    # the box beyond f1 = 1 (10 x 11) plus the integral of 10 + sqrt(f1) over [0, 1]
    assert mq.zdt1_front_hypervolume([11.0, 11.0]) == pytest.approx(110 + 10 + 2 / 3, abs=1e-12)


@pytest.mark.parametrize("ref", [[1.1, 1.1, 1.1], [1.5, 2.0, 1.2]])
def test_dtlz2_beyond_the_sphere_is_the_box_less_its_octant(ref):
    assert mq.dtlz2_front_hypervolume(ref) == pytest.approx(np.prod(ref) - np.pi / 6, abs=1e-6)


@pytest.mark.parametrize("ref", [[0.6, 1.4, 1.5], [0.8, 0.9, 1.3], [0.7, 0.7, 0.7]])
def test_dtlz2_cut_by_the_reference_against_monte_carlo(ref):
    ref = np.asarray(ref)
    u = np.random.default_rng(0).random((400_000, 3)) * ref
    outside_ball = np.linalg.norm(u, axis=1) >= 1.0
    mc, se = np.prod(ref) * outside_ball.mean(), np.prod(ref) * outside_ball.std() / np.sqrt(len(u))
    assert abs(mq.dtlz2_front_hypervolume(ref) - mc) < 4 * se + 1e-6


def test_branin_currin_front_reaches_and_bounds_the_known_maximum():
    front = mq.branin_currin_front()
    ref = np.array([18.0, 6.0])
    full = mq._staircase_hypervolume(front, ref)
    # BoTorch's BraninCurrin._max_hv (59.3601) is below what these evaluated points reach.
    assert 59.36 < full < 59.41
    assert full == pytest.approx(mq.PROBLEMS["BraninCurrin"]["max_hv"], abs=1e-4)
    # No run's points dominate more than the front: 2000 random points and the best of a grid.
    x = np.random.default_rng(1).random((2000, 2))
    for r in (ref, np.array([200.0, 12.0])):
        assert hypervolume(mq.branin_currin(x), r) < mq.PROBLEMS["BraninCurrin"]["front_hv"](r)


@pytest.mark.parametrize("name", [name for name, problem in mq.PROBLEMS.items() if problem["front_hv"]])
def test_front_hypervolume_about_the_problem_reference_is_max_hv(name):
    problem = mq.PROBLEMS[name]
    assert problem["front_hv"](problem["ref"]) == pytest.approx(problem["max_hv"], abs=1e-4)


# --- 3-objective problems: DTLZ5, DTLZ7, VehicleSafety ---------------------------


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 60))
def test_sweep_3d_is_the_exact_hypervolume_and_front(seed, n):
    rng = np.random.default_rng(seed)
    y, ref = rng.random((n, 3)), rng.uniform(0.2, 1.2, 3)
    keep, hv = mq._sweep_3d(y, ref)
    assert hv == pytest.approx(hypervolume(y, ref), rel=1e-12, abs=1e-12)
    below = np.all(y < ref, axis=1)
    assert np.array_equal(keep[below], pareto_mask(y[below])) and not keep[~below].any()
    keep, _ = mq._sweep_3d(y)
    assert np.array_equal(keep, pareto_mask(y))


def test_dtlz5_known_values():
    # last inputs 0.5: g = 0, theta_1 = 1/2, so the point (cos t / sqrt 2, cos t / sqrt 2, sin t)
    x0 = np.array([0.0, 0.3, 1.0])
    x = np.c_[x0, np.array([0.1, 0.7, 0.9]), np.full((3, 4), 0.5)]
    t = 0.5 * np.pi * x0
    np.testing.assert_allclose(mq.dtlz5(x), np.c_[np.cos(t) / np.sqrt(2), np.cos(t) / np.sqrt(2), np.sin(t)], atol=1e-15)
    # all last inputs 0: g = 4 / 4 = 1, theta_1 = (1 + 2 x_1) / 4; x = (0, 1, 0, ...) -> 2 (cos 3pi/8, sin 3pi/8, 0)
    np.testing.assert_allclose(mq.dtlz5(np.array([[0.0, 1.0, 0, 0, 0, 0]])),
                               [[2 * np.cos(3 * np.pi / 8), 2 * np.sin(3 * np.pi / 8), 0.0]], atol=1e-15)


def test_dtlz7_known_values():
    # last inputs 0: g = 1, f_2 = 6 - phi(f_0) - phi(f_1), phi(t) = t (1 + sin 3 pi t)
    x = np.array([[0.0, 0.0, 0, 0, 0, 0], [1 / 6, 1 / 6, 0, 0, 0, 0], [0.5, 1.0, 0, 0, 0, 0]])
    np.testing.assert_allclose(mq.dtlz7(x), [[0, 0, 6], [1 / 6, 1 / 6, 6 - 2 / 3], [0.5, 1.0, 6 - 0 - 1]], atol=1e-14)
    # all last inputs 1: g = 10, f_2 = 11 (3 - ...) ; at f = 0: 33
    np.testing.assert_allclose(mq.dtlz7(np.array([[0.0, 0.0, 1, 1, 1, 1]])), [[0, 0, 33]], atol=1e-12)


def test_vehicle_safety_known_values():
    # inputs 1 (x = 0) and 3 (x = 1): the polynomials of Tanabe and Ishibuchi's RE3-5-4 by hand
    ones = [1640.2823 + 2.3573285 + 2.3220035 + 4.5688768 + 7.7213633 + 4.4559504,
            6.5856 + 1.15 - 1.0427 + 0.9738 + 0.8364 - 0.3695 + 0.0861 + 0.3628 - 0.1106 - 0.3437 + 0.1764,
            -0.0551 + 0.0181 + 0.1024 + 0.0421 - 0.0073 + 0.024 - 0.0118 - 0.0204 - 0.008 - 0.0241 + 0.0109]
    threes = [1640.2823 + 3 * (2.3573285 + 2.3220035 + 4.5688768 + 7.7213633 + 4.4559504),
              6.5856 + 3 * (1.15 - 1.0427 + 0.9738 + 0.8364) + 9 * (-0.3695 + 0.0861 + 0.3628 - 0.1106 - 0.3437 + 0.1764),
              -0.0551 + 3 * (0.0181 + 0.1024 + 0.0421) + 9 * (-0.0073 + 0.024 - 0.0118 - 0.0204 - 0.008 - 0.0241 + 0.0109)]
    np.testing.assert_allclose(mq.vehicle_safety(np.array([[0.0] * 5, [1.0] * 5])), [ones, threes], rtol=1e-14)


def test_dtlz5_front_beyond_the_curve_is_closed_form():
    # ref >= (1, 1, 1): the box less the integral over u_2 in [0, 1] of (r_0 + r_1) w - w^2,
    # w = sqrt((1 - u_2^2) / 2): prod(ref) - (r_0 + r_1) pi / (4 sqrt 2) + 1 / 3
    for ref in ([10.0, 10.0, 10.0], [1.0, 2.0, 1.5]):
        exact = np.prod(ref) - (ref[0] + ref[1]) * np.pi / (4 * np.sqrt(2)) + 1 / 3
        assert mq.dtlz5_front_hypervolume(ref) == pytest.approx(exact, abs=1e-8)
    assert mq.PROBLEMS["DTLZ5 (d=6, m=3)"]["max_hv"] == pytest.approx(1000 - 20 * np.pi / (4 * np.sqrt(2)) + 1 / 3, abs=1e-4)


@pytest.mark.parametrize("ref", [[0.8, 0.9, 1.2], [0.6, 1.5, 0.9], [2.0, 2.0, 2.0]])
def test_dtlz5_front_against_monte_carlo_and_samples(ref):
    ref = np.asarray(ref)
    u = np.random.default_rng(0).random((400_000, 3)) * ref
    dominated = 2 * np.minimum(u[:, 0], u[:, 1]) ** 2 + u[:, 2] ** 2 >= 1.0
    mc, se = np.prod(ref) * dominated.mean(), np.prod(ref) * dominated.std() / np.sqrt(len(u))
    exact = mq.dtlz5_front_hypervolume(ref)
    assert abs(exact - mc) < 4 * se + 1e-6
    # no input reaches beyond the curve; points of the curve dominate a little less than it
    y = mq.dtlz5(np.random.default_rng(1).random((20_000, 6)))
    assert np.all(2 * np.minimum(y[:, 0], y[:, 1]) ** 2 + y[:, 2] ** 2 >= 1.0 - 1e-12)
    assert mq._sweep_3d(y, ref)[1] <= exact + 1e-9
    x0 = np.linspace(0, 1, 5001)
    curve = mq.dtlz5(np.c_[x0, np.zeros_like(x0), np.full((len(x0), 4), 0.5)])
    assert 0 <= exact - mq._sweep_3d(curve, ref)[1] < 1e-3 * np.prod(ref)


@pytest.mark.parametrize("ref", [[0.8, 0.9, 5.5], [0.5, 1.2, 6.0], [15.0, 15.0, 15.0]])
def test_dtlz7_front_against_monte_carlo_and_samples(ref):
    ref = np.asarray(ref, np.float64)
    rng = np.random.default_rng(0)
    fine = np.linspace(0.0, 1.0, 200_001)
    run_max = np.maximum.accumulate(mq._dtlz7_phi(fine))
    phi = lambda t: run_max[np.round(np.minimum(t, 1.0) * 200_000).astype(int)]  # noqa: E731
    u = rng.random((400_000, 3)) * ref
    dominated = u[:, 2] >= 6.0 - phi(u[:, 0]) - phi(u[:, 1])
    mc, se = np.prod(ref) * dominated.mean(), np.prod(ref) * dominated.std() / np.sqrt(len(u))
    exact = mq.dtlz7_front_hypervolume(ref)
    assert abs(exact - mc) < 4 * se + 1e-3
    # random inputs and a dense sample of the front (last inputs 0) dominate no more than it
    assert mq._sweep_3d(mq.dtlz7(rng.random((20_000, 6))), ref)[1] <= exact + 1e-9
    x = np.c_[rng.random((20_000, 2)), np.zeros((20_000, 4))]
    sampled = mq._sweep_3d(mq.dtlz7(x), ref)[1]
    assert sampled <= exact + 1e-9 and exact - sampled < 0.03 * exact  # 20 000 points: staircase gaps


def test_vehicle_safety_front_reaches_and_bounds_the_known_maximum():
    front = mq.vehicle_safety_front()
    problem = mq.PROBLEMS["VehicleSafety"]
    ref = np.asarray(problem["ref"])
    full = problem["front_hv"](ref)
    # BoTorch's VehicleSafety._max_hv (246.816, from Tanabe and Ishibuchi's approximate front)
    # is below what the sampled front reaches; denser samples give 247.372
    assert 246.816 < full < 247.38
    # random inputs add next to nothing to the front (they are dominated by it or nearly so)
    y = mq.vehicle_safety(np.random.default_rng(3).random((20_000, 5)))
    for r in (ref, ref + np.array([50.0, 2.0, 0.1]), np.array([1670.0, 9.0, 0.2])):
        alone = problem["front_hv"](r)
        assert mq._sweep_3d(y, r)[1] < alone
        assert mq._sweep_3d(np.r_[front, y], r)[1] - alone < 2e-4 * max(alone, 1e-9)


def test_new_problems_equal_botorch():
    torch = require("torch")
    mo = require("botorch.test_functions.multi_objective")
    x = np.random.default_rng(0).random((500, 6))
    for ours, theirs, inputs in [
        (mq.dtlz2, mo.DTLZ2(dim=6, num_objectives=3), x),
        (mq.dtlz5, mo.DTLZ5(dim=6, num_objectives=3), x),
        (mq.dtlz7, mo.DTLZ7(dim=6, num_objectives=3), x),
        (mq.vehicle_safety, mo.VehicleSafety(), x[:, :5]),
        (mq.branin_currin, mo.BraninCurrin(), x[:, :2]),
    ]:
        lo, hi = theirs.bounds.numpy()
        expected = theirs(torch.from_numpy(lo + (hi - lo) * inputs)).numpy()
        np.testing.assert_allclose(ours(inputs), expected, rtol=1e-12, atol=1e-12)
    for name, cls in [("DTLZ5 (d=6, m=3)", mo.DTLZ5), ("DTLZ7 (d=6, m=3)", mo.DTLZ7)]:
        assert mq.PROBLEMS[name]["ref"] == cls(dim=6, num_objectives=3).ref_point.tolist()
    assert mq.PROBLEMS["VehicleSafety"]["ref"] == pytest.approx(mo.VehicleSafety().ref_point.tolist(), rel=1e-12)


# --- the held-out problems: ZDT2, ZDT3 (noisy), DTLZ2 with four objectives, CarSideImpact ------


@settings(max_examples=25, deadline=None)
@given(ref=refs_2d)
def test_zdt2_closed_form_against_a_dense_front(ref):
    f1 = np.linspace(0.0, 1.0, 20001)
    front = np.stack([f1, 1.0 - f1**2], axis=1)
    sampled = mq._staircase_hypervolume(front, np.asarray(ref))
    exact = mq.zdt2_front_hypervolume(ref)
    assert sampled <= exact + 1e-12
    assert exact - sampled < 1e-3 * max(ref[1], 1.0)


def test_zdt2_and_zdt3_inputs_never_pass_their_fronts():
    x = np.random.default_rng(2).random((20_000, 6))
    for f, front_hv in ((mq.zdt2, mq.zdt2_front_hypervolume), (mq.zdt3, mq.zdt3_front_hypervolume)):
        for ref in ([11.0, 11.0], [0.9, 1.2], [0.5, 0.5]):
            assert mq._staircase_hypervolume(f(x), np.asarray(ref)) <= front_hv(ref) + 1e-9
    # on g = 1 (last inputs 0) ZDT3 is its front's curve
    f1 = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(mq.zdt3(np.c_[f1, np.zeros((101, 5))])[:, 1], 1 - np.sqrt(f1) - f1 * np.sin(10 * np.pi * f1))


def test_dtlz2_with_four_objectives_lies_beyond_the_unit_sphere_and_its_maximum_is_closed_form():
    y = mq.dtlz2(np.random.default_rng(4).random((5000, 6)), m=4)
    assert y.shape == (5000, 4) and np.all(np.linalg.norm(y, axis=1) >= 1.0 - 1e-12)
    on_front = mq.dtlz2(np.c_[np.random.default_rng(5).random((50, 3)), np.full((50, 3), 0.5)], m=4)
    np.testing.assert_allclose(np.linalg.norm(on_front, axis=1), 1.0, atol=1e-12)
    # the unit 4-ball's volume is pi^2 / 2, its positive orthant a sixteenth: against Monte Carlo
    u = np.random.default_rng(6).random((400_000, 4)) * 1.1
    outside = np.linalg.norm(u, axis=1) >= 1.0
    mc, se = 1.1**4 * outside.mean(), 1.1**4 * outside.std() / np.sqrt(len(u))
    assert abs(mq.dtlz2_m4_front_hypervolume([1.1] * 4) - mc) < 4 * se


@pytest.mark.parametrize("ref", [[0.9, 1.2, 0.7, 1.05], [2.0, 0.3, 1.5, 0.8], [0.95, 0.95, 0.95, 0.95], [0.5] * 4])
def test_dtlz2_with_four_objectives_cut_by_the_reference_against_monte_carlo(ref):
    # a run's own reference (its warm-up's worst plus 10 %) may lie inside the ball in some objective
    u = np.random.default_rng(8).random((400_000, 4)) * np.array(ref)
    outside = np.linalg.norm(u, axis=1) >= 1.0
    mc, se = np.prod(ref) * outside.mean(), np.prod(ref) * outside.std() / np.sqrt(len(u))
    assert abs(mq.dtlz2_m4_front_hypervolume(ref) - mc) <= 4 * se + 1e-12
    assert mq.dtlz2_m4_front_hypervolume(ref) <= np.prod(ref)


def test_the_noisy_problem_sees_7_world_means_and_repeats_them_per_seed():
    problem = mq.PROBLEMS["ZDT3 (d=6), noisy"]
    x = np.random.default_rng(7).random((20_000, 6))
    noise = mq.observer(problem, 0)(x) - mq.zdt3(x)
    np.testing.assert_allclose(noise.std(axis=0), np.array([0.0852, 0.1773]) / np.sqrt(7), rtol=0.03)
    np.testing.assert_array_equal(mq.observer(problem, 3)(x[:10]), mq.observer(problem, 3)(x[:10]))
    assert mq.observer(mq.PROBLEMS["ZDT2 (d=6)"], 0) is mq.zdt2


def test_held_out_problems_equal_botorch():
    torch = require("torch")
    mo = require("botorch.test_functions.multi_objective")
    x = np.random.default_rng(0).random((500, 7))
    for ours, theirs, inputs in [
        (mq.zdt2, mo.ZDT2(dim=6), x[:, :6]),
        # BoTorch's ZDT3 leaves out the factor g of f2 (mq.zdt3's docstring)
        (lambda v: mq.zdt3(v) / np.c_[np.ones(len(v)), 1.0 + 9.0 * v[:, 1:].mean(axis=1)], mo.ZDT3(dim=6), x[:, :6]),
        (lambda v: mq.dtlz2(v, m=4), mo.DTLZ2(dim=6, num_objectives=4), x[:, :6]),
        (mq.car_side_impact, mo.CarSideImpact(), x),
    ]:
        lo, hi = theirs.bounds.numpy()
        expected = theirs(torch.from_numpy(lo + (hi - lo) * inputs)).numpy()
        np.testing.assert_allclose(ours(inputs), expected, rtol=1e-12, atol=1e-12)
    for name, cls in (("ZDT2 (d=6)", mo.ZDT2(dim=6)), ("CarSideImpact", mo.CarSideImpact()),
                      ("DTLZ2 (d=6, m=4)", mo.DTLZ2(dim=6, num_objectives=4)), ("ZDT3 (d=6), noisy", mo.ZDT3(dim=6))):
        assert mq.PROBLEMS[name]["ref"] == pytest.approx(cls.ref_point.tolist(), rel=1e-12)
    # on the front g = 1, where the two ZDT3s agree, our sampled front's maximum is BoTorch's
    assert mq.PROBLEMS["ZDT3 (d=6), noisy"]["max_hv"] == pytest.approx(mo.ZDT3._max_hv, abs=1e-4)
