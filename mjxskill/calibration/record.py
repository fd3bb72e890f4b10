"""Recordings made in a twin instead of on a robot: the calibration loop shown and tested without one.

``record_episodes`` runs episodes of a twin (usually a "true" twin whose physics the calibrated
one does not know: ``true_twin``) on the native engine's plain loop, one control step at a time,
and samples what a robot's sensors would give (``mjxskill.calibration.recording``'s arrays) at
``rate`` Hz: the joint angles, the joint torques the controller commanded, the tracked object's
pose and the tool's contact force (its mean over the sample period, as a force sensor's
anti-aliasing filter gives it), each with Gaussian noise of the scenario's
``calibration.noise`` (one standard deviation; the orientation as a rotation about a random axis).
The start is recorded as a robot knows it too: the arm's start configuration with the encoders'
noise, the placed objects' start poses as the tracker's mean of ``START_SAMPLES`` samples. So the
replay never starts from the twin's exact state: it does not meet the recording's chaotic
contact history by construction, as it never would on a robot (``mjxskill.calibration.replay``).

The episodes: the scenario's operator parameter sets in turn (``manual_parameters``) with a small
uniform change each (``jitter``, m), from its training start configurations in turn, the objects
placed as a training world places them (``randomization.xy_sigma``), the world's friction the
twin's own (the randomized range not drawn: a real object has one friction).
"""

from __future__ import annotations

import jax
import mujoco
import numpy as np

from mjxskill.calibration.recording import FORMAT
from mjxskill.engine.common.bindings import FREE, MOCAP
from mjxskill.engine.common.worlds import Worlds
from mjxskill.engine.native.rollout import NativeRollout
from mjxskill.scenario.schema import Scenario
from mjxskill.task import PlannedTask
from mjxskill.calibration.twin import with_values

START_SAMPLES = 50  # the tracker's samples at rest that give an object's start pose (0.5 s at 100 Hz)
# The "true" twin of the experiment: the pushed object heavier, stickier, its centre of mass moved
TRUE_CHANGES = {"mass": 1.2, "friction": 1.5, "com_offset.x": 0.02}


def true_twin(scn: Scenario, changes: dict[str, float] | None = None) -> Scenario:
    """``scn`` with its tracked object changed by ``changes`` (``TRUE_CHANGES`` by default): mass
    and friction multiplied, a ``com_offset`` coordinate moved by the value (m); one friction in
    every world (the randomization's range dropped)."""
    assert scn.calibration is not None
    name = scn.calibration.tracked
    obj = scn.objects[name]
    values = {}
    for field, change in (TRUE_CHANGES if changes is None else changes).items():
        if field.startswith("com_offset."):
            values[f"{name}.{field}"] = float(obj.com_offset["xyz".index(field[-1])]) + change
        else:
            values[f"{name}.{field}"] = float(getattr(obj, field)) * change
    return with_values(scn, values, friction_range=None)


def episode_plan(scn: Scenario, task: PlannedTask, engine: NativeRollout, episodes: int, seed: int, jitter: float):
    """(params (E, P), worlds (E,)) of ``episodes`` recordings (see the module docstring)."""
    rng = np.random.default_rng(seed)
    sets = [np.array([s.values[n] for n in task.parameter_names]) for s in scn.manual_parameters.values()]
    if not sets:
        sets = [np.asarray(task.defaults, float)]
    low, high = np.asarray(task.bounds[0], float), np.asarray(task.bounds[1], float)
    params = np.array([np.clip(sets[k % len(sets)] + rng.uniform(-jitter, jitter, len(low)), low, high)
                       for k in range(episodes)])
    worlds = jax.tree.map(np.asarray, engine.sample_worlds(jax.random.key(seed), episodes))
    worlds = jax.tree.map(lambda x: x[:, 0], worlds)
    configs = scn.robot.start_configs
    worlds = worlds._replace(config_index=np.arange(episodes, dtype=np.int32) % len(configs),
                             arm_qpos=np.asarray(configs, np.float32)[np.arange(episodes) % len(configs)],
                             friction=np.full(episodes, np.nan, np.float32))
    return params, worlds


class _Sampler:
    """What the sensors read, every ``every`` control steps (``on_step`` of the plain loop)."""

    def __init__(self, model: mujoco.MjModel, body: int, sensors: list[int], every: int):
        self.model, self.body, self.sensors, self.every = model, body, sensors, every
        self.rows: list[np.ndarray] = []
        self.force, self.steps = 0.0, 0

    def __call__(self, data: mujoco.MjData, tau: np.ndarray) -> None:
        self.steps += 1
        self.force += float(np.sum(data.sensordata[self.sensors]))
        if self.steps % self.every == 0:
            self.rows.append(np.concatenate([[data.time], data.qpos[:7], data.xpos[self.body], data.xquat[self.body],
                                             [self.force / self.every], tau]))
            self.force = 0.0


def _rotate_noise(quat: np.ndarray, sd_rad: float, rng) -> np.ndarray:
    """``quat`` (T, 4) each turned by a small random rotation (rotation vector ~ N(0, sd^2) per axis)."""
    out = np.empty_like(quat)
    for k, q in enumerate(quat):
        turn = np.zeros(4)
        mujoco.mju_axisAngle2Quat(turn, *_axis_angle(rng.normal(0.0, sd_rad, 3)))
        mujoco.mju_mulQuat(out[k], turn, q)
        out[k] *= np.sign(out[k][0]) or 1.0
    return out


def _axis_angle(vector: np.ndarray):
    angle = float(np.linalg.norm(vector))
    return (vector / angle if angle > 0 else np.array([1.0, 0.0, 0.0])), angle


def record_episodes(scn: Scenario, task: PlannedTask, episodes: int = 10, *, seed: int = 0, rate: float = 100.0,
                    jitter: float = 0.01, noise: bool = True, source: str = "") -> list[dict]:
    """``episodes`` recordings of ``task`` in the twin ``scn`` (see the module docstring), each as
    the arrays of ``mjxskill.calibration.recording`` (name -> array; write one with
    ``write_npz``). ``noise``: False records the twin's exact values."""
    engine = NativeRollout(scn, task, worlds=1)
    params, worlds = episode_plan(scn, task, engine, episodes, seed, jitter)
    assert scn.calibration is not None
    tracked = scn.calibration.tracked
    model = engine.mj_model
    body = model.body(scn.objects[tracked].mjcf_body).id
    every = max(1, int(round(scn.control_hz / rate)))
    sd = scn.calibration.noise if noise else {k: 0.0 for k in scn.calibration.noise}
    rng = np.random.default_rng(seed + 1)
    placed = [k for k, s in enumerate(engine.setup.bindings.slots) if s.how in (FREE, MOCAP)]
    out = []
    for k in range(episodes):
        world = Worlds(*(np.asarray(x)[k] for x in worlds))
        sampler = _Sampler(model, body, list(engine.setup.bindings.force_sensors), every)
        engine.run_episode(params[k], world, on_step=sampler)
        rows = np.array(sampler.rows)
        t = len(rows)
        out.append({
            "format": FORMAT, "robot": scn.robot.name, "source": source,
            "time": rows[:, 0],
            "joint_position": rows[:, 1:8] + rng.normal(0.0, sd["joint_position"], (t, 7)),
            "object_position": rows[:, 8:11] + rng.normal(0.0, sd["object_position"], (t, 3)),
            "object_quaternion": _rotate_noise(rows[:, 11:15], np.radians(sd["object_orientation_deg"]), rng),
            "tool_force": rows[:, 15] + rng.normal(0.0, sd["tool_force"], t),
            "joint_torque": rows[:, 16:23],
            "parameter_names": np.array(task.parameter_names),
            "parameter_values": params[k],
            # the start as the robot knows it: its encoders, and the tracker's mean over half a second at rest
            "start_configuration": np.asarray(world.arm_qpos, float) + rng.normal(0.0, sd["joint_position"], 7),
            "start_object_names": np.array([engine.setup.bindings.slots[j].name for j in placed]),
            "start_positions": np.asarray(world.object_pos, float)[placed]
            + rng.normal(0.0, sd["object_position"] / np.sqrt(START_SAMPLES), (len(placed), 3)),
            "start_quaternions": _rotate_noise(np.asarray(world.object_quat, float)[placed],
                                               np.radians(sd["object_orientation_deg"]) / np.sqrt(START_SAMPLES), rng),
        })
    return out


__all__ = ["TRUE_CHANGES", "record_episodes", "true_twin"]
