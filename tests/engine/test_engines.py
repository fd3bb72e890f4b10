"""Both physics engines satisfy the one ``Rollout`` interface (``mjxskill.engine.protocol``), and so
do the native engine's wrappers (worker processes, a Ray cluster); ``build_rollout`` builds each
of them."""

import inspect

import numpy as np
import pytest

from mjxskill.engine import build_rollout
from mjxskill.engine.common.types import EpisodeSetup
from mjxskill.engine.protocol import Rollout

MEMBERS = [name for name in dir(Rollout) if not name.startswith("_")] + ["__call__"]


@pytest.mark.parametrize("engine, workers", [("mjx", 1), ("native", 1), ("native", 2)])
def test_each_engine_satisfies_the_protocol(push_task, engine, workers):
    scn, task = push_task
    rollout = build_rollout(scn, task, engine, worlds=3, episode_seconds=0.2, workers=workers)
    try:
        assert isinstance(rollout, Rollout)
        for name in MEMBERS:
            assert hasattr(rollout, name), name
        assert isinstance(rollout.setup, EpisodeSetup)
        assert rollout.worlds == 3 and rollout.episode_seconds == pytest.approx(0.2)
        assert rollout.parameter_names == task.parameter_names
        np.testing.assert_array_equal(rollout.bounds, task.bounds)
        assert rollout.objective_names == scn.objective_names
        assert rollout.reward_names == tuple(r.name for r in scn.rewards)
        assert rollout.control_steps_per_episode == rollout.setup.ticks * rollout.setup.steps_per_tick
        with pytest.raises(ValueError, match=r"params must have shape \(B, 4\)"):
            rollout.check_params(np.zeros((2, 3)))
        with pytest.raises(ValueError, match="params must be finite"):
            rollout.check_params(np.full((1, 4), np.nan))
    finally:
        rollout.close()
    rollout.close()  # twice is harmless
    with build_rollout(scn, task, engine, worlds=1, episode_seconds=0.2, workers=workers) as again:
        assert isinstance(again, Rollout)


def test_the_native_engine_is_one_process_wrapped_by_where_its_episodes_run(push_task):
    from mjxskill.engine.native import NativeRollout, ProcessPoolRollout

    scn, task = push_task
    alone = build_rollout(scn, task, "native", worlds=1, episode_seconds=0.2, workers=1)
    pooled = build_rollout(scn, task, "native", worlds=1, episode_seconds=0.2, workers=2)
    assert type(alone) is NativeRollout
    assert isinstance(pooled, ProcessPoolRollout) and isinstance(pooled.inner, NativeRollout) and pooled.workers == 2
    assert pooled.task is pooled.inner.task and pooled.mj_model is pooled.inner.mj_model
    with pytest.raises(ValueError, match="only the native engine runs on a Ray cluster"):
        build_rollout(scn, task, "mjx", worlds=1, cluster=object())


def test_mjx_on_a_cluster_is_refused_before_connecting():
    from mjxskill.engine.build import connect_cluster
    from mjxskill.errors import ClusterError

    assert connect_cluster(None, "mjx") is None  # no address: this machine
    with pytest.raises(ClusterError, match="runs the native engine's episodes; this run's engine is mjx"):
        connect_cluster("127.0.0.1:1", "mjx")


def test_the_protocol_names_every_method_both_engines_share():
    # what callers use must be in the protocol, with the same parameters on both engines and the wrappers
    from mjxskill.engine.mjx.compiled import MJXRollout
    from mjxskill.engine.native import NativeRollout, ProcessPoolRollout, RayRollout

    for name in ("__call__", "run_worlds", "sample_worlds", "worlds_per_config", "trace", "close"):
        expected = list(inspect.signature(getattr(Rollout, name)).parameters)
        for cls in (MJXRollout, NativeRollout, ProcessPoolRollout, RayRollout):
            got = list(inspect.signature(getattr(cls, name)).parameters)
            assert got[:len(expected)] == expected, (cls.__name__, name, got)
