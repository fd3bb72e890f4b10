"""Both physics engines satisfy the one ``Rollout`` interface (``mjxskill.engine.protocol``), and
``build_rollout`` builds each of them."""

import inspect

import numpy as np
import pytest

from mjxskill.engine import build_rollout
from mjxskill.engine.common.types import EpisodeSetup
from mjxskill.engine.protocol import Rollout
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task

MEMBERS = [name for name in dir(Rollout) if not name.startswith("_")] + ["__call__"]


@pytest.fixture(scope="module")
def push():
    scn = load_scenario("push")
    return scn, plan_task(scn)


@pytest.mark.parametrize("engine", ["mjx", "native"])
def test_each_engine_satisfies_the_protocol(push, engine):
    scn, task = push
    rollout = build_rollout(scn, task, engine, worlds=3, episode_seconds=0.2, workers=1)
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
    with build_rollout(scn, task, engine, worlds=1, episode_seconds=0.2, workers=1) as again:
        assert isinstance(again, Rollout)


def test_the_protocol_names_every_method_both_engines_share():
    # what callers use must be in the protocol, with the same parameters on both engines
    from mjxskill.engine.mjx.compiled import MJXRollout
    from mjxskill.engine.native.rollout import NativeRollout

    for name in ("__call__", "run_worlds", "sample_worlds", "worlds_per_config", "trace", "close"):
        expected = list(inspect.signature(getattr(Rollout, name)).parameters)
        for cls in (MJXRollout, NativeRollout):
            got = list(inspect.signature(getattr(cls, name)).parameters)
            assert got[:len(expected)] == expected, (cls.__name__, name, got)
