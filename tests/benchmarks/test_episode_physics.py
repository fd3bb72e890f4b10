"""benchmarks/episode_physics.py replays the episodes' own steps: ``mujoco.rollout`` (and ``Batch.rollout``) driven by the
recorded inputs ends every episode in the state the plain loop (the reference interpreter over
native MuJoCo) ended it in, and the figures count the replayed steps."""

import json
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
import episode_physics as ep


def test_the_replay_ends_where_the_plain_loop_ended(tmp_path):
    out = tmp_path / "physics.json"
    result = ep.main(["--task", "push", "--seconds", "0.4", "--sets", "2", "--worlds", "2", "--json", str(out)])
    assert result == json.loads(out.read_text())
    assert result["episodes"] == 4 and result["episodes_replayed"] == 4
    assert result["replay_max_state_error"] == 0.0  # deterministic physics: the very states
    assert result["one_core_steps_per_s"] > 0 and result["all_cores_steps_per_s"] > 0
    for replay in ("recorded", "unrecorded"):  # the limit is the faster of the two replays
        assert result["all_cores_steps_per_s"] >= result[f"{replay}_all_cores_steps_per_s"] > 0


def test_a_recording_holds_the_inputs_of_every_step():
    from throughput import workload

    _, _, params, worlds, engine = workload("push", 0.2, 1, 1)
    recording = ep.record(engine, params, worlds)
    steps = engine.control_steps_per_episode
    assert recording["inputs"].shape[:2] == (1, steps)
    # The arm's torques change from step to step: a recording of one step repeated would not.
    assert np.ptp(recording["inputs"][0, :, :7], axis=0).max() > 0
    _, replayed, error = ep.replay(recording, threads=2, runs=1)
    assert replayed == 2 and error == 0.0  # the one episode twice, once per thread
    # A negative control: the replay is not exact by construction; without the torques it ends elsewhere.
    no_torque = dict(recording, inputs=recording["inputs"].copy())
    no_torque["inputs"][..., :7] = 0.0
    assert ep.replay(no_torque, threads=1, runs=1)[2] > 1e-6


def test_the_unrecorded_replay_ends_where_the_plain_loop_ended():
    from throughput import workload

    _, _, params, worlds, engine = workload("peg", 0.3, 2, 1)
    recording = ep.record(engine, params, worlds)
    _, replayed, error = ep.replay_unrecorded(recording, threads=2, runs=1)
    assert replayed == 2 and error == 0.0
    no_torque = dict(recording, inputs=recording["inputs"].copy())
    no_torque["inputs"][..., :7] = 0.0
    assert ep.replay_unrecorded(no_torque, threads=1, runs=1)[2] > 1e-6


def test_paired_shares_time_the_engine_and_the_replay_in_turn(monkeypatch):
    """Each round's share is the engine's rate over the replay's, from one replay and one call timed
    in turn, the order alternating, after one untimed replay. The replay counts the episodes it
    replays (4: three repeated to a multiple of two threads), not the recording's: 2 s for 4 x 10
    steps and a call of 3 s for 60 steps both take 1/20 s a step (share 1); a call of 6 s halves
    the share. Each timer spans only its own part (the replay moves the clock too)."""
    clock, log = [0.0], []
    monkeypatch.setattr(ep.time, "perf_counter", lambda: clock[0])

    class FakeReplay:
        episodes, nstep = 4, 10

        def __init__(self, recording, threads):
            assert threads == 2
            log.append("built")

        def run(self):
            log.append("replay")
            clock[0] += 2.0
            return 2.0

    def call(seconds):
        def run():
            log.append("engine")
            clock[0] += seconds
        return run

    monkeypatch.setattr(ep, "UnrecordedReplay", FakeReplay)
    recording = {"inputs": np.zeros((3, 10, 1))}
    assert ep.paired_shares(recording, 2, call(3.0), steps=60, rounds=3) == [1.0, 1.0, 1.0]
    assert log == ["built", "replay", "replay", "engine", "engine", "replay", "replay", "engine"]
    assert ep.paired_shares(recording, 2, call(6.0), steps=60, rounds=2) == [0.5, 0.5]
    assert ep.paired_shares(recording, 2, call(6.0), steps=60, rounds=0) == []


def test_no_paired_share_when_an_episode_diverged_or_without_the_calls_steps(monkeypatch):
    """A diverged episode is not replayed but the engine's call counts it: no share is reported
    then, and one is with every episode replayed. An engine's call without its step count is refused."""
    for name in ("replay", "replay_unrecorded"):
        monkeypatch.setattr(ep, name, lambda recording, threads, runs=2: (1.0, 2, 0.0))
    monkeypatch.setattr(ep, "paired_shares", lambda recording, threads, call, steps, rounds: [0.9] * rounds)
    recording = {"models": ["one"], "inputs": np.zeros((1, 10, 1))}
    for episodes, shares in ((2, None), (1, [0.9, 0.9])):
        monkeypatch.setattr(ep, "record", lambda engine, params, worlds: dict(recording, episodes=episodes))
        assert ep.measure(None, None, None, 2, call=lambda: None, steps=10, rounds=2).get("paired_shares") == shares
    with pytest.raises(ValueError, match="control steps"):
        ep.measure(None, None, None, 2, call=lambda: None, rounds=2)
