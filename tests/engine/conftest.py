"""Fixtures of the engines' tests (tests/engine/ and its folders)."""

import pytest


@pytest.fixture(scope="module")
def push_task():
    """The push scenario and its planned task: (scenario, PlannedTask)."""
    from mjxskill import load_scenario, plan_task

    scn = load_scenario("push")
    return scn, plan_task(scn)


@pytest.fixture(scope="session")
def push_rollout():
    """The push task compiled once for the session: 2 worlds per parameter set, 8 s episodes
    (the push ends in the goal corner after about 7 s). Callers keep 2 parameter sets per call
    so that every call reuses the one compiled program."""
    from mjxskill import compile_rollout, load_scenario

    scn = load_scenario("push")
    return scn, compile_rollout(scn, worlds=2, episode_seconds=8.0)
