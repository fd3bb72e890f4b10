"""The benchmark problems' whole-front hypervolumes (benchmarks/mobo_quality.py), which the
regret about a run's own reference point divides by: against the exact hypervolume code, a
closed form and Monte Carlo."""

import os
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "benchmarks"))
import mobo_quality as mq  # noqa: E402

from mjxskill.gp import hypervolume  # noqa: E402

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


@pytest.mark.parametrize("name", list(mq.PROBLEMS))
def test_front_hypervolume_about_the_problem_reference_is_max_hv(name):
    problem = mq.PROBLEMS[name]
    assert problem["front_hv"](problem["ref"]) == pytest.approx(problem["max_hv"], abs=1e-4)
