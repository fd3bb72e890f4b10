"""pareto_mask against brute force; hypervolume against inclusion-exclusion, Monte Carlo and known values."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from mjxskill.gp import hypervolume, pareto_mask


def _brute_force_front(y):
    n = len(y)
    keep = []
    for i in range(n):
        if not np.all(np.isfinite(y[i])):
            keep.append(False)
            continue
        dominated = any(
            np.all(np.isfinite(y[j])) and np.all(y[j] <= y[i]) and np.any(y[j] < y[i]) for j in range(n)
        )
        duplicate_earlier = any(np.array_equal(y[j], y[i]) for j in range(i))
        keep.append(not dominated and not duplicate_earlier)
    return np.array(keep, bool)


def _inclusion_exclusion_hv(y, ref):
    """Exact union volume of the boxes [y_i, ref]: sum over subsets of (-1)^(|S|+1) vol(meet)."""
    y = np.asarray([p for p in y if np.all(p < ref)])
    total = 0.0
    for k in range(1, len(y) + 1):
        for subset in itertools.combinations(range(len(y)), k):
            corner = np.max(y[list(subset)], axis=0)
            total += (-1) ** (k + 1) * np.prod(ref - corner)
    return total


def test_hand_built_front_with_dominated_and_duplicate_points():
    y = np.array([[1.0, 5.0], [2.0, 3.0], [2.0, 3.0], [3.0, 3.0], [4.0, 1.0], [5.0, 5.0]])
    assert pareto_mask(y).tolist() == [True, True, False, False, True, False]
    assert pareto_mask(y, deduplicate=False).tolist() == [True, True, True, False, True, False]


def test_empty_nan_and_single_inputs():
    assert pareto_mask(np.zeros((0, 2))).shape == (0,)
    y = np.array([[np.nan, 0.0], [1.0, 1.0], [np.inf, -5.0]])
    assert pareto_mask(y).tolist() == [False, True, False]
    assert hypervolume(np.zeros((0, 2)), [1.0, 1.0]) == 0.0
    assert hypervolume(y, [2.0, 2.0]) == pytest.approx(1.0)


def test_bad_shapes_raise_clear_errors():
    with pytest.raises(ValueError, match="shape"):
        pareto_mask(np.zeros(3))
    with pytest.raises(ValueError, match="reference point"):
        hypervolume(np.zeros((2, 2)), [1.0, 1.0, 1.0])


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(0, 12), st.integers(2, 3)), elements=st.sampled_from([0.0, 1.0, 2.0, 3.0, 0.5])))
def test_pareto_mask_matches_brute_force(y):
    np.testing.assert_array_equal(pareto_mask(y), _brute_force_front(y))


@settings(max_examples=60, deadline=None)
@given(
    arrays(
        np.float64,
        st.tuples(st.integers(1, 7), st.integers(2, 4)),
        elements=st.floats(0.0, 1.2, allow_nan=False).map(lambda v: round(v, 2)),
    )
)
def test_hypervolume_matches_inclusion_exclusion(y):
    ref = np.ones(y.shape[1])
    assert hypervolume(y, ref) == pytest.approx(_inclusion_exclusion_hv(y, ref), rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("m", [2, 3])
def test_hypervolume_matches_monte_carlo(m):
    rng = np.random.default_rng(m)
    y = rng.random((30, m)) ** 2
    ref = np.full(m, 1.1)
    samples = rng.random((400_000, m)) * ref
    dominated = np.zeros(len(samples), bool)
    for p in y:
        dominated |= np.all(samples >= p, axis=1)
    mc = dominated.mean() * np.prod(ref)
    stderr = np.sqrt(dominated.mean() * (1 - dominated.mean()) / len(samples)) * np.prod(ref)
    assert abs(hypervolume(y, ref) - mc) < 5 * stderr


def test_known_values():
    assert hypervolume(np.array([[0.0, 0.0]]), [2.0, 3.0]) == pytest.approx(6.0)
    # Two boxes 2x1 and 1x2 overlapping in 1x1: 3.
    assert hypervolume(np.array([[0.0, 1.0], [1.0, 0.0]]), [2.0, 2.0]) == pytest.approx(3.0)
    # Three 2x1x1 boxes whose pairwise and triple overlaps are all the unit cube [1, 2]^3.
    y3 = np.array([[0.0, 1.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 0.0]])
    assert hypervolume(y3, [2.0, 2.0, 2.0]) == pytest.approx(3 * 2 - 3 * 1 + 1)
    # ZDT1's front f2 = 1 - sqrt(f1) with ref (11, 11): 121 - 1/3 = 120.6667 in the limit.
    f1 = np.linspace(0, 1, 2001)
    front = np.stack([f1, 1 - np.sqrt(f1)], 1)
    assert hypervolume(front, [11.0, 11.0]) == pytest.approx(120.6667, abs=1e-3)
