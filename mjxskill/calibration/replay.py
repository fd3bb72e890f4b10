"""How a recorded episode is replayed in the twin for the fit's residual, and the residual itself.

**The replay: the skill run again, closed loop.** For every recording the twin runs the recorded
skill with the recorded parameters from the recorded start (the arm's start configuration, the
objects where they stood): the behavior tree, the impedance controller and the physics, as a
training episode runs (the native engine's plain loop, ``NativeRollout.run_episode``), on the
model ``sysid`` compiled with the candidate values (``sysid``'s ``custom_rollout`` hook). The
simulated joint angles, object pose and tool force are compared with the recorded ones.

Why not the two replays the issue names:

* *The recorded torques, open loop.* The arm integrates every difference between its model and
  the robot (friction, the torques' noise, the links' inertia) with nothing to hold it on its
  path; in contact the object's motion then feeds back into the arm's. The recorded torques
  carry the controller's reaction to the object as the robot met it, not as the twin meets it.
* *The arm following its recorded joint path* (a stiff joint servo in the twin, the object's
  physics fitted): the pusher then becomes rigid where the robot's was compliant (the skill
  pushes at 700 N/m), so the contact force is set by the servo and the contact's stiffness, not by
  the object. Measured on ten pushes of the "true" twin without noise (``docs/calibration.md``):
  replayed at the true values, the object's pose was 2-9 mm RMS off its recording and, once the
  object was jammed in the goal corner, the force up to 150 N off (of 20-50 N); over the free
  push alone the residual was lower at 3.3 kg and friction 0.27 than at the true 3.0 and 0.3,
  and lower with the centre of mass 2 cm off along the push than at the true one: a quasi-static
  push with a rigid pusher shows mass and friction only as their product, and the path replay's
  own errors chose the point along it.

Closed loop, the arm's compliance is simulated as the robot's controller makes it: the joint
angles record the force the object opposed (the controller's stiffness turns it into a
deflection), which sets mass apart from friction. The cost is a model of the controller (the
twin's, the one the skills are learned with) and chaos: contact over the whole 12 s episode
makes the replay chaotic (a change of 1 g in the mass changed the joints over the episode as
much as one of 100 g: the prism turns one way or the other in the corner). So the residual
covers only the **window** where the object is pushed free of fixtures (``window``): from half
a second before the tracked object first moves to the sample
where it comes within ``GAP`` of a geom it can collide with other than the robot's and what it
stood on at the start (the fence and the stop of the push's goal corner). Within the window the
replay is still chaotic at small scales (a change of 1 g moves the joints by about 3e-4 rad),
which the fit's finite differences step over (``mjxskill.calibration.fit``).

The residual (``modify_residual``): per sample of the window, the recorded minus the simulated
joint angles, object position, orientation (quaternion, signs matched) and tool force, each in
units of its signal's noise (``calibration.noise``); the force of both averaged over
``FORCE_WINDOW`` (the twin's contact chatters at the 2 ms control step, which no force sensor
resolves) and the simulated one over the recording's sample period first, as the sensor averages.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
from mujoco import sysid

from mjxskill.calibration.recording import Recording
from mjxskill.engine.common.bindings import FREE, MOCAP
from mjxskill.engine.common.worlds import Worlds
from mjxskill.engine.native.episode import initial_data
from mjxskill.engine.native.rollout import NativeRollout
from mjxskill.errors import RecordingError
from mjxskill.scenario.schema import Scenario
from mjxskill.task import PlannedTask

GAP = 0.005  # m: the window ends when the tracked object comes this close to a fixture
PRE_ROLL = 0.5  # s of the window before the object first moves
FORCE_WINDOW = 0.05  # s: forces are compared as means over this long
MIN_WINDOW_SAMPLES = 20
# the recorded signals and their columns, one scalar each (sysid's report plots one per column)
SIGNALS = {
    "joint_position": tuple(f"joint{j}" for j in range(1, 8)),
    "object_position": ("object_x", "object_y", "object_z"),
    "object_quaternion": ("object_qw", "object_qx", "object_qy", "object_qz"),
    "tool_force": ("tool_force",),
}
ALL_COLUMNS = tuple(c for columns in SIGNALS.values() for c in columns)


def moved_threshold(noise: dict) -> float:
    """m: how far the tracked object must move from its start to count as pushed."""
    return max(0.005, 5.0 * noise["object_position"])


@dataclass
class Replay:
    """One recording prepared for the fit: its ``world`` and skill ``params``, its window
    ``[first, last)`` of samples, the episode length the replay needs, the measured signals
    (``measured``, a sysid TimeSeries of ``columns``) and each column's noise (``sd``)."""

    recording: Recording
    world: Worlds
    first: int
    last: int
    seconds: float
    measured: object
    sd: np.ndarray
    columns: tuple[str, ...]
    initial_state: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))


def world_of(rec: Recording, engine: NativeRollout) -> Worlds:
    """The engine's world of the recording: its start configuration, the placed objects where
    it found them (others as the scenario places them), the model's own friction."""
    slots = engine.setup.bindings.slots
    pos = np.array([s.position for s in slots], np.float32).reshape(-1, 3)
    quat = np.array([s.quat for s in slots], np.float32).reshape(-1, 4)
    for k, slot in enumerate(slots):
        if slot.name in rec.start_poses and slot.how in (FREE, MOCAP):
            pos[k], quat[k] = rec.start_poses[slot.name]
    fields: list = [np.int32(0), np.asarray(rec.start_configuration, np.float32), pos, quat, np.float32(np.nan)]
    return Worlds(*fields)  # host values, as the native engine takes them


def _fixture_geoms(model: mujoco.MjModel, body: int, robot: set[int], data: mujoco.MjData, own: list[int]) -> list[int]:
    """Geoms the tracked body's geoms can touch (a contact pair, or contype/conaffinity) that
    are not the robot's nor within GAP of it at the start (what it stands on)."""
    partners = set()
    for g in own:
        for a, b in zip(model.pair_geom1, model.pair_geom2):
            if g in (a, b):
                partners.add(int(b if a == g else a))
        for h in range(model.ngeom):
            if (model.geom_contype[g] & model.geom_conaffinity[h]) or (model.geom_contype[h] & model.geom_conaffinity[g]):
                partners.add(h)
    partners = {h for h in partners if int(model.geom_bodyid[h]) not in robot and int(model.geom_bodyid[h]) != body}
    return [h for h in sorted(partners) if min(_distance(model, data, g, h) for g in own) >= GAP]


def _distance(model, data, g: int, h: int) -> float:
    return float(mujoco.mj_geomDistance(model, data, g, h, 0.1, None))


def _robot_bodies(model: mujoco.MjModel) -> set[int]:
    """The arm and what it carries: the subtree of the first joint's body's root."""
    root = int(model.body_rootid[int(model.jnt_bodyid[0])])
    return {b for b in range(model.nbody) if int(model.body_rootid[b]) == root}


def window(rec: Recording, engine: NativeRollout, body_name: str, noise: dict) -> tuple[int, int]:
    """[first, last) samples of ``rec`` the residual covers (the module docstring). RecordingError
    when the tracked object never moves, or meets a fixture at once."""
    pos = rec.object_position
    start = np.median(pos[: max(1, int(round(PRE_ROLL / rec.period))), :2], axis=0)
    moved = np.linalg.norm(pos[:, :2] - start, axis=1) > moved_threshold(noise)
    if not moved.any():
        raise RecordingError(f"{rec.path}: object_position: the tracked object never moves more than "
                             f"{moved_threshold(noise) * 1000:.0f} mm from where it starts: the recording holds "
                             "nothing of its physics")
    first = max(1, int(np.argmax(moved)) - int(round(PRE_ROLL / rec.period)))
    model = engine.mj_model
    data = initial_data(engine, model, world_of(rec, engine))
    body = model.body(body_name).id
    own = [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) == body]
    fixtures = _fixture_geoms(model, body, _robot_bodies(model), data, own)
    adr = int(model.jnt_qposadr[int(model.body_jntadr[body])])
    last = len(rec.time)
    for i in range(first, len(rec.time)):
        data.qpos[adr:adr + 3], data.qpos[adr + 3:adr + 7] = pos[i], rec.object_quaternion[i]
        mujoco.mj_kinematics(model, data)
        if any(_distance(model, data, g, h) < GAP for g in own for h in fixtures):
            last = i
            break
    if last - first < MIN_WINDOW_SAMPLES:
        raise RecordingError(f"{rec.path}: object_position: the tracked object meets a fixture "
                             f"{rec.time[last] - rec.time[first]:.2f} s after the window starts: too little of a "
                             "free push to fit")
    return first, last


def prepare(scn: Scenario, task: PlannedTask, recordings: list[Recording], model: mujoco.MjModel) -> list[Replay]:
    """Each recording's window, world and measured signals (``model``: the nominal twin's)."""
    assert scn.calibration is not None
    noise = dict(scn.calibration.noise)
    engine = NativeRollout(scn, task, worlds=1, mj_model=model)
    body_name = scn.objects[scn.calibration.tracked].mjcf_body
    assert body_name is not None  # the tracked object has a body (mjxskill.scenario.calibration)
    quat_sd = np.sin(np.radians(noise["object_orientation_deg"]) / 2)
    out = []
    for rec in recordings:
        # a mean of n samples has 1/sqrt(n) of one's noise
        sd_of = {"joint_position": noise["joint_position"], "object_position": noise["object_position"],
                 "object_quaternion": quat_sd,
                 "tool_force": noise["tool_force"] / np.sqrt(max(1.0, round(FORCE_WINDOW / rec.period)))}
        first, last = window(rec, engine, body_name, noise)
        names = [n for n in SIGNALS if n != "tool_force" or rec.tool_force is not None]
        arrays = [np.asarray(getattr(rec, n), float).reshape(len(rec.time), -1) for n in names]
        if "tool_force" in names:
            arrays[-1] = _trailing_mean(arrays[-1], max(1, int(round(FORCE_WINDOW / rec.period))))
        columns = tuple(c for n in names for c in SIGNALS[n])
        measured = sysid.TimeSeries.from_custom_map(
            np.asarray(rec.time[first:last], float), np.concatenate(arrays, axis=1)[first:last],
            [(c, 1, sysid.SignalType.CustomObs) for c in columns])
        sd = np.concatenate([[sd_of[n]] * len(SIGNALS[n]) for n in names])
        seconds = min(scn.episode_seconds, np.ceil((rec.time[last - 1] + 0.05) * scn.bt_hz) / scn.bt_hz)
        world = world_of(rec, engine)
        state = sysid.create_initial_state(model, np.array(initial_data(engine, model, world).qpos))
        out.append(Replay(rec, world, first, last, float(seconds), measured, sd, columns, state))
    return out


def _trailing_mean(x: np.ndarray, n: int) -> np.ndarray:
    """The mean of each sample and the ``n - 1`` before it (fewer at the start), per column."""
    c = np.cumsum(np.concatenate([np.zeros((1,) + x.shape[1:]), x]), axis=0)
    k = np.arange(1, len(x) + 1)
    lo = np.maximum(0, k - n)
    return (c[k] - c[lo]) / (k - lo).reshape((-1,) + (1,) * (x.ndim - 1))


class _Probe:
    """Every control step of a replay: time, joint angles, tracked pose, tool force, the state."""

    def __init__(self, model: mujoco.MjModel, body: int, sensors: list[int], steps: int):
        self.model, self.body, self.sensors = model, body, sensors
        self.size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        self.rows = np.zeros((steps, 16))
        self.state = np.zeros((steps, self.size))
        self.k = 0

    def __call__(self, data: mujoco.MjData, tau: np.ndarray) -> None:
        if self.k >= len(self.rows):
            return
        row = self.rows[self.k]
        row[0] = data.time
        row[1:8] = data.qpos[:7]
        row[8:11], row[11:15] = data.xpos[self.body], data.xquat[self.body]
        row[15] = float(np.sum(data.sensordata[self.sensors]))
        mujoco.mj_getState(self.model, data, self.state[self.k], mujoco.mjtState.mjSTATE_FULLPHYSICS)
        self.k += 1


class Replayer:
    """``sysid``'s ``custom_rollout`` and ``modify_residual`` for ``replays``: the episodes run
    again in the candidate models (found by the initial state and measured series sysid passes,
    which are the ``Replay``'s own objects)."""

    def __init__(self, scn: Scenario, task: PlannedTask, replays: list[Replay]):
        self.scn, self.task = scn, task
        self.by_state = {id(r.initial_state): r for r in replays}
        self.by_measured = {id(r.measured): r for r in replays}
        self.episodes = 0

    def custom_rollout(self, models, datas, control_signal, initial_states, **_):
        """One replay per model (sysid's finite differences pass several): SystemTrajectory each."""
        out = []
        for model, control, state in zip(models, control_signal, initial_states):
            replay = self.by_state[id(state)]
            out.append(self._replay(model, replay, control, state))
        return out

    def _replay(self, model: mujoco.MjModel, replay: Replay, control, state: np.ndarray):
        assert self.scn.calibration is not None
        engine = NativeRollout(self.scn, self.task, worlds=1, episode_seconds=replay.seconds, mj_model=model)
        body = model.body(self.scn.objects[self.scn.calibration.tracked].mjcf_body).id
        probe = _Probe(model, body, list(engine.setup.bindings.force_sensors), engine.setup.ticks * engine.setup.steps_per_tick)
        engine.run_episode(replay.recording.parameters, replay.world, on_step=probe)
        self.episodes += 1
        rows, states = probe.rows[: probe.k], probe.state[: probe.k]
        simulated = sysid.TimeSeries.from_custom_map(rows[:, 0], rows[:, 1:],
                                                     [(c, 1, sysid.SignalType.CustomObs) for c in ALL_COLUMNS])
        return sysid.SystemTrajectory(model=model, control=control, sensordata=simulated, initial_state=state,
                                      state=sysid.TimeSeries(rows[:, 0], states))

    def modify_residual(self, params, predicted, measured, model, return_pred_all, state=None, **_):
        """(residual (N, C), the simulated series on the measured samples, the measured series)."""
        replay = self.by_measured[id(measured)]
        times = measured.times
        period = replay.recording.period
        sim = sysid.TimeSeries.slice_by_name(predicted, list(replay.columns))
        data = sim.data.copy()
        if "tool_force" in replay.columns:
            steps = max(1, int(round(period / float(model.opt.timestep))))
            data[:, -1:] = _trailing_mean(data[:, -1:], steps)
        on_samples = sysid.TimeSeries(sim.times, data).resample(times).data
        if "tool_force" in replay.columns:
            on_samples[:, -1:] = _trailing_mean(on_samples[:, -1:], max(1, int(round(FORCE_WINDOW / period))))
        q = slice(10, 14)
        flip = np.sum(on_samples[:, q] * measured.data[:, q], axis=1) < 0
        on_samples[flip, q] *= -1
        residual = (measured.data - on_samples) / replay.sd
        return residual, sysid.TimeSeries(times, on_samples, measured.signal_mapping), measured


__all__ = ["FORCE_WINDOW", "GAP", "Replay", "Replayer", "prepare", "window", "world_of"]
