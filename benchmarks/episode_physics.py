"""The episodes' own physics: MuJoCo's step on the states the training episodes visit, with no
Python, on one core and on all cores at once. The ceiling of any engine that runs these episodes
on this machine (issue 48).

    python benchmarks/episode_physics.py --task push              # 6 sets x 7 worlds, full episodes
    python benchmarks/episode_physics.py --task peg --json FILE

How: the plain loop (``NativeRollout.run_episode``, the reference) runs every episode of the batch
once and records, per episode, its model (the world's contact friction set) and initial full
physics state, and the user inputs (``mjSTATE_USER``: the controller's torques and whatever else
the episode sets) of every control step. The recorded inputs are then replayed open loop, in C,
each thread stepping whole episodes with no Python between steps, two ways: by ``mujoco.rollout``
(``replay``), which writes every step's full state and sensors to its outputs, and by
``mujoco.batch.Batch.rollout`` (``replay_unrecorded``), which writes only the sensors; the
recording costs 4-42 % of the replay here (benchmarks/NOTES.md section 46), and is not the
episodes' physics, so the faster replay is the limit. Because the episode is deterministic, a
replay visits the recorded states; ``replay_max_state_error`` (the largest difference of any
final full physics state from the recording's, over both) shows it. Each replay is timed (the
best of two runs, its output buffers touched before) on one thread and on one thread per core
(``default_workers``, the cores this process may run on), all stepping at once, so cores that
share a physical core, or memory bandwidth, show in the ratio; the episodes are repeated to a
multiple of the threads so that none waits for a last odd episode. An episode that diverged is
left out of the replay (its last steps' inputs may be a reset's); with none left, the figures are
None.

The figures: ``one_core_steps_per_s``, ``all_cores_steps_per_s`` (the faster replay's: the limit an
engine is measured against, ``episode_physics_limit_steps_per_s`` in ``throughput.py``'s JSON),
each replay's as ``recorded_*`` and ``unrecorded_*``, and ``all_cores_over_one_core``; control
steps (one ``mj_step`` each) per second of wall time, the load average before and after.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

USER_INPUTS = "mjSTATE_USER"  # ctrl, applied forces, mocap, eq_active, userdata: whatever an episode sets


def full_state(model, data):
    """(nstate,) the data's ``mjSTATE_FULLPHYSICS`` state: what an episode starts and ends in."""
    import mujoco
    import numpy as np

    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, full))
    mujoco.mj_getState(model, data, state, full)
    return state


def record(engine, params, worlds) -> dict:
    """Per episode of the batch (``params`` (B, P), ``worlds`` of leading shape (B, W)) that did
    not diverge: its model, initial state (``mjSTATE_FULLPHYSICS``), the user inputs of each step
    and the final full physics state, stacked over those episodes; ``episodes``: the batch's count
    (with none kept, only ``models`` (empty) and ``episodes``)."""
    import jax
    import numpy as np

    from mjxskill.engine.native.episode import initial_data

    models, starts, inputs, finals = [], [], [], []
    b, w = worlds.config_index.shape
    for i in range(b):
        for j in range(w):
            world = jax.tree.map(lambda x: np.asarray(x)[i, j], worlds)
            model = copy.copy(engine.mj_model)  # initial_data sets the world's friction on it
            start = full_state(model, initial_data(engine, model, world))
            recorder = Recorder(model)
            if engine.run_episode(params[i], world, on_step=recorder).diverged:
                continue
            models.append(model)
            starts.append(start)
            inputs.append(np.stack(recorder.rows))
            finals.append(full_state(model, recorder.data))
    if not models:
        return dict(models=[], episodes=b * w)
    return dict(models=models, starts=np.stack(starts), inputs=np.stack(inputs), finals=np.stack(finals),
                episodes=b * w)


class Recorder:
    """``on_step`` for ``run_episode``: each step's user inputs (still in the data after the step:
    ``mj_step`` does not change them), and the data, whose state after the last step is the
    episode's end."""

    def __init__(self, model):
        import mujoco

        self.model, self.spec = model, getattr(mujoco.mjtState, USER_INPUTS)
        self.size = mujoco.mj_stateSize(model, self.spec)
        self.rows, self.data = [], None

    def __call__(self, data, _tau) -> None:
        import mujoco
        import numpy as np

        row = np.empty(self.size)
        mujoco.mj_getState(self.model, data, row, self.spec)
        self.rows.append(row)
        self.data = data


def threads_order(n: int, threads: int):
    """The n recorded episodes repeated to a multiple of ``threads`` (each thread steps whole
    episodes, and none waits for a last odd one): their indices in replay order."""
    import numpy as np

    return np.arange(-(-n // threads) * threads) % n


def replay(recording: dict, threads: int, runs: int = 2) -> tuple[float, int, float]:
    """(wall seconds, the best of ``runs``; episodes replayed; the largest difference of a final
    full physics state from the recording's) of ``mujoco.rollout`` replaying the recorded
    episodes on ``threads`` threads at once, repeated to a multiple of ``threads``."""
    import mujoco
    import numpy as np
    from mujoco import rollout

    n, nstep = recording["inputs"].shape[:2]
    order = threads_order(n, threads)
    models = [recording["models"][i] for i in order]
    starts, inputs = recording["starts"][order], recording["inputs"][order]
    datas = [mujoco.MjData(models[0]) for _ in range(threads)]
    spec = getattr(mujoco.mjtState, USER_INPUTS).value
    nstate = mujoco.mj_stateSize(models[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    state = np.empty((len(order), nstep, nstate))
    sensordata = np.empty((len(order), nstep, models[0].nsensordata))
    state.fill(0.0), sensordata.fill(0.0)  # the pages touched before the clock runs
    seconds = []
    # One episode per task: the threads take whole episodes in turn.
    with rollout.Rollout(nthread=threads) as runner:
        for _ in range(runs):
            t0 = time.perf_counter()
            runner.rollout(models, datas, starts, inputs, control_spec=spec, state=state, sensordata=sensordata,
                           chunk_size=1)
            seconds.append(time.perf_counter() - t0)
    error = float(np.max(np.abs(state[:, -1] - recording["finals"][order])))
    return min(seconds), len(order), error


class UnrecordedReplay:
    """The recorded episodes on one ``mujoco.batch.Batch`` of ``threads`` threads, each simulation
    on its episode's model (``set_models``), replayed by ``Batch.rollout`` recording nothing but
    each step's ``sensordata`` (the smallest output it takes; ``mujoco.rollout`` records every
    step's full state too): MuJoCo's step alone. ``run()`` replays them all from their starts and
    returns its wall seconds; ``error()`` the largest difference of a final full physics state
    from the recording's. ``episodes``: how many it replays (``threads_order``)."""

    def __init__(self, recording: dict, threads: int):
        import mujoco
        import numpy as np
        from mujoco.batch import Batch

        n, self.nstep = recording["inputs"].shape[:2]
        self.recording, self.order = recording, threads_order(n, threads)
        self.episodes = len(self.order)
        self.models = [recording["models"][i] for i in self.order]
        full, self.user = mujoco.mjtState.mjSTATE_FULLPHYSICS, getattr(mujoco.mjtState, USER_INPUTS)
        integration = mujoco.mjtState.mjSTATE_INTEGRATION
        self.batch = Batch(self.models[0], self.episodes, nthread=threads)
        self.batch.set_models(self.models)
        self.starts = np.empty((self.episodes, self.batch.nstate))
        for row, i in enumerate(self.order):  # the recorded start and the world's first inputs (its mocap poses)
            data = mujoco.MjData(self.models[row])
            mujoco.mj_setState(self.models[row], data, recording["starts"][i], full)
            mujoco.mj_setState(self.models[row], data, recording["inputs"][i, 0], self.user)
            mujoco.mj_getState(self.models[row], data, self.starts[row], integration)
        self.inputs = np.ascontiguousarray(recording["inputs"][self.order])
        self.out = {"sensordata": np.zeros((self.episodes, self.nstep, self.models[0].nsensordata))}

    def run(self) -> float:
        self.batch.state[:] = self.starts
        t0 = time.perf_counter()
        self.batch.rollout(self.nstep, control=self.inputs, control_spec=self.user.value, record=("sensordata",),
                           out=self.out)
        return time.perf_counter() - t0

    def error(self) -> float:
        import numpy as np

        finals = self.recording["finals"]
        return max(float(np.max(np.abs(full_state(self.models[row], self.batch.get_data(row)) - finals[i])))
                   for row, i in enumerate(self.order))


def replay_unrecorded(recording: dict, threads: int, runs: int = 2) -> tuple[float, int, float]:
    """As ``replay``, by ``UnrecordedReplay``."""
    replayer = UnrecordedReplay(recording, threads)
    seconds = min(replayer.run() for _ in range(runs))
    return seconds, replayer.episodes, replayer.error()


def paired_shares(recording: dict, threads: int, call, steps: int, rounds: int) -> list[float]:
    """Per round, an engine's rate (``call()`` runs the batch, ``steps`` control steps) over the
    all-cores replay's (one ``UnrecordedReplay.run``, on a batch built and run once before the
    rounds: its first run pays for memory its later ones reuse), the two timed in turn in the
    same minutes, the order alternating (this machine's rate moves by up to 30 % between calls
    minutes apart, so a share of figures measured minutes apart moves with it)."""
    replayer = UnrecordedReplay(recording, threads)
    replayer.run()
    shares = []
    for r in range(rounds):
        seconds = {}
        for what in ("replay", "engine") if r % 2 == 0 else ("engine", "replay"):
            if what == "replay":
                seconds[what] = replayer.run() / (replayer.episodes * replayer.nstep)
            else:
                t0 = time.perf_counter()
                call()
                seconds[what] = (time.perf_counter() - t0) / steps
        shares.append(seconds["replay"] / seconds["engine"])
    return shares


def measure(engine, params, worlds, cores: int, call=None, steps: int = 0, rounds: int = 0) -> dict:
    """The figures of the module docstring for this batch; with ``call`` (an engine's call on it,
    ``steps`` control steps), also ``paired_shares`` over ``rounds`` (``paired_shares``), unless
    an episode diverged."""
    if call is not None and steps <= 0:
        raise ValueError(f"an engine's call needs its control steps, got {steps}")
    load_before = os.getloadavg()[0]
    recording = record(engine, params, worlds)
    result = dict(episodes=recording["episodes"], episodes_replayed=len(recording["models"]), cores=cores,
                  one_core_steps_per_s=None, all_cores_steps_per_s=None, all_cores_over_one_core=None,
                  replay_max_state_error=None, load_avg_before=load_before)
    if recording["models"]:
        nstep, errors = recording["inputs"].shape[1], []
        for name, replayer in (("recorded", replay), ("unrecorded", replay_unrecorded)):
            for where, threads in (("one_core", 1), ("all_cores", cores)):
                seconds, episodes, error = replayer(recording, threads)
                result[f"{name}_{where}_steps_per_s"] = episodes * nstep / seconds
                errors.append(error)
        for where in ("one_core", "all_cores"):  # the faster replay: MuJoCo's step with the least around it
            result[f"{where}_steps_per_s"] = max(result[f"recorded_{where}_steps_per_s"],
                                                 result[f"unrecorded_{where}_steps_per_s"])
        result["replay_max_state_error"] = max(errors)
        result["all_cores_over_one_core"] = result["all_cores_steps_per_s"] / result["one_core_steps_per_s"]
        # an engine's diverged episode stops early and the replay leaves it out: their steps differ
        if call is not None and rounds and result["episodes_replayed"] == result["episodes"]:
            result["paired_shares"] = paired_shares(recording, cores, call, steps, rounds)
    result["load_avg_after"] = os.getloadavg()[0]
    return result


def report(r: dict) -> str:
    if r["all_cores_steps_per_s"] is None:
        return f"the episodes' own physics: not measured, every one of the {r['episodes']} episodes diverged"
    return (f"the episodes' own physics ({r['episodes_replayed']} of {r['episodes']} episodes replayed by "
            f"mujoco.rollout and by Batch.rollout, the faster counting ({r['unrecorded_all_cores_steps_per_s']:.0f} "
            f"and {r['recorded_all_cores_steps_per_s']:.0f} unrecorded and recorded on all cores), final state "
            f"within {r['replay_max_state_error']:.1e} of the recording): "
            f"{r['one_core_steps_per_s']:.0f} control steps/s on one core, {r['all_cores_steps_per_s']:.0f} on "
            f"{r['cores']} at once ({r['all_cores_over_one_core']:.2f} x one core); load {r['load_avg_before']:.2f} "
            f"before, {r['load_avg_after']:.2f} after")


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--task", default="push", help="scenario (push, peg or a YAML path)")
    parser.add_argument("--seconds", type=float, default=None, help="episode length, s (default: the scenario's)")
    parser.add_argument("--sets", type=int, default=6, help="parameter sets (default 6, the training batch)")
    parser.add_argument("--worlds", type=int, default=None, help="worlds per set (default: the scenario's)")
    parser.add_argument("--json", type=Path, help="write the figures here")
    args = parser.parse_args(argv)

    import mjxskill  # noqa: F401

    from mjxskill.engine.native.pool import default_workers
    from throughput import workload  # benchmarks/: the same parameter sets and worlds as the engines'

    scn, _, params, worlds, engine = workload(args.task, args.seconds, args.sets, args.worlds)
    result = dict(task=scn.name, episode_seconds=engine.episode_seconds, **measure(engine, params, worlds, default_workers()))
    print(report(result), flush=True)
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
