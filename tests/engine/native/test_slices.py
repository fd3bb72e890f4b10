"""How a call's episodes are split over a pool's workers (``rollout.episode_slices``) and put back
(``rollout.in_order``): every episode in exactly one slice, the slices' sizes within one of each
other, each parameter set's worlds spread over the workers, and the results back in order."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from mjxskill.engine.native.rollout import episode_slices, in_order


@given(st.integers(0, 200), st.integers(1, 16))
def test_every_episode_is_in_one_slice_and_comes_back_in_order(n_episodes, n_slices):
    parts = episode_slices(n_episodes, n_slices)
    assert len(parts) == min(n_episodes, n_slices)
    assert sorted(np.concatenate(parts).tolist() if parts else []) == list(range(n_episodes))
    if parts:
        assert max(map(len, parts)) - min(map(len, parts)) <= 1
    # each slice's results, here the episode's own index as a worker would return it
    assert in_order(parts, [[int(i) for i in part] for part in parts]) == list(range(n_episodes))


@given(st.integers(1, 12), st.integers(2, 12), st.integers(2, 4))
def test_each_parameter_sets_worlds_are_spread_over_the_workers(sets, worlds, workers):
    # episodes are sets x worlds, set-major: a set's worlds go to min(worlds, workers) workers,
    # not all to one (contiguous slices gave a set that barely touches the object to one worker)
    parts = episode_slices(sets * worlds, workers)
    for s in range(sets):
        holding = [k for k, part in enumerate(parts) if np.any(part // worlds == s)]
        assert len(holding) == min(worlds, workers)
