"""One executed episode as the robot recorded it: the file ``python -m mjxskill.calibrate`` reads.

A recording is a NumPy ``.npz`` archive (one file: typed arrays and their names, read without
pickle) holding these arrays (T samples, P skill parameters, K placed objects):

======================== =========== ====================================================================
array                    shape       what
======================== =========== ====================================================================
``format``               ()          ``"mjxskill-recording/1"``
``robot``                ()          the robot's name as the scenario names it (``robot.name``)
``time``                 (T,)        s since the skill started (its first tick), increasing; >= 20 Hz
``joint_position``       (T, 7)      rad, the arm's measured joint angles
``object_position``      (T, 3)      m, world frame: the tracked object (the scenario's ``calibration.tracked``)
``object_quaternion``    (T, 4)      its orientation (w, x, y, z)
``parameter_names``      (P,)        the skill parameters run: every learnable parameter of the plan
``parameter_values``     (P,)        their values, inside the skills' bounds
``start_configuration``  (7,)        rad, the arm's joint angles when the skill started
``start_object_names``   (K,)        objects of the scenario placed in the cell (free or mocap bodies)
``start_positions``      (K, 3)      m, where each was at the start (others: the scenario's pose)
``start_quaternions``    (K, 4)      its orientation then (w, x, y, z)
``tool_force``           (T,)        optional: N, the contact force on the tool, averaged over the sample period
``joint_torque``         (T, 7)      optional: Nm, the measured joint torques (shown in the report)
``source``               ()          optional: text, where the recording came from
======================== =========== ====================================================================

``read_recording`` checks a file against this and against the scenario and plan it is used
with (the robot, the joint count, the parameters and their bounds, finite values, enough samples
at a high enough rate); a bad file is one ``RecordingError`` naming the file, the array and,
for a value, its sample and time. ``write_npz`` writes one (``mjxskill.calibration.record``
makes them from a twin).
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mjxskill._files import read_regular
from mjxskill.errors import RecordingError, listing, quote

FORMAT = "mjxskill-recording/1"
REQUIRED = ("format", "robot", "time", "joint_position", "object_position", "object_quaternion", "parameter_names",
            "parameter_values", "start_configuration", "start_object_names", "start_positions", "start_quaternions")
OPTIONAL = ("tool_force", "joint_torque", "source")
MIN_SAMPLES = 50  # a push takes seconds: fewer samples are no episode
MAX_PERIOD = 0.05  # s: a contact lasts a few tenths of a second; coarser samples miss it
MAX_BYTES = 512 * 2**20  # an hour at 1 kHz is about 100 MB
N_JOINTS = 7


@dataclass(frozen=True, eq=False)
class Recording:
    """A checked recording (arrays read-only, float64; see the module docstring). ``parameters``:
    the values in the plan's order of ``parameter_names``; ``path``: the file it was read from."""

    path: str
    robot: str
    time: np.ndarray
    joint_position: np.ndarray
    object_position: np.ndarray
    object_quaternion: np.ndarray
    parameters: np.ndarray
    start_configuration: np.ndarray
    start_poses: dict
    tool_force: np.ndarray | None = None
    joint_torque: np.ndarray | None = None
    source: str = ""

    @property
    def period(self) -> float:
        """The median sample period, s."""
        return float(np.median(np.diff(self.time)))


def _frozen(array) -> np.ndarray:
    out = np.array(array, dtype=np.float64)
    out.flags.writeable = False
    return out


class _Reader:
    """The arrays of one archive, each checked as it is taken; errors name the file and array."""

    def __init__(self, path: Path, arrays: dict):
        self.path, self.arrays = path, arrays

    def fail(self, name: str | None, message: str):
        where = f"{self.path}: {name}" if name else str(self.path)
        raise RecordingError(f"{where}: {message}")

    def text(self, name: str) -> str:
        value = self.arrays[name]
        if value.shape != () or value.dtype.kind not in "US":
            self.fail(name, f"expected one text value, got an array of shape {value.shape} ({value.dtype})")
        return str(value)

    def names(self, name: str) -> list[str]:
        value = self.arrays[name]
        if value.ndim != 1 or value.dtype.kind not in "US":
            self.fail(name, f"expected a list of names, got shape {value.shape} ({value.dtype})")
        return [str(v) for v in value]

    def numbers(self, name: str, shape: tuple, time=None) -> np.ndarray:
        """A float array of ``shape`` (None: any length there); every value finite."""
        value = self.arrays[name]
        if value.dtype.kind not in "fiu":
            self.fail(name, f"expected numbers, got {value.dtype}")
        if value.ndim != len(shape) or any(s is not None and s != v for s, v in zip(shape, value.shape)):
            want = "(" + ", ".join("T" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
            self.fail(name, f"expected shape {want}, got {value.shape}")
        value = value.astype(np.float64)
        bad = np.argwhere(~np.isfinite(value))
        if len(bad):
            index = tuple(int(i) for i in bad[0])
            at = f"[{', '.join(map(str, index))}]" if value.ndim else ""
            when = f" (t = {time[index[0]]:.3f} s)" if time is not None and value.ndim else ""
            self.fail(f"{name}{at}", f"not a finite number ({value[index]}){when}; {len(bad)} such value(s) in all")
        return value


def _load(path: Path) -> dict:
    try:
        data = read_regular(path, MAX_BYTES)
    except OSError as err:
        raise RecordingError(f"{path}: cannot read the recording ({err.strerror or err})") from None
    if len(data) > MAX_BYTES:
        raise RecordingError(f"{path}: larger than {MAX_BYTES // 2**20} MB: not a recording of one episode")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as err:
        raise RecordingError(f"{path}: not a NumPy .npz archive of arrays ({str(err)[:120]})") from None


def read_recording(path, scn, task) -> Recording:
    """The recording at ``path``, checked against the scenario ``scn`` (its robot, its
    ``calibration.tracked`` object's placement) and the plan ``task`` (its learnable parameters
    and bounds). RecordingError (one line: file, array, sample) for anything else."""
    path = Path(path)
    r = _Reader(path, _load(path))
    missing = [k for k in REQUIRED if k not in r.arrays]
    unknown = sorted(set(r.arrays) - set(REQUIRED) - set(OPTIONAL))
    if unknown:
        r.fail(None, f"unknown array {quote(unknown[0])}; a recording holds {listing(REQUIRED + OPTIONAL)}")
    if missing:
        r.fail(None, f"missing array {quote(missing[0])}; a recording holds {listing(REQUIRED)} "
                     f"(and optionally {listing(OPTIONAL)})")
    if r.text("format") != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {quote(r.text('format'))}")
    robot = r.text("robot")
    if robot != scn.robot.name:
        r.fail("robot", f"recorded on {quote(robot)}, but the scenario's robot is {quote(scn.robot.name)}: "
                        "a recording is only used with the twin of the robot it was made on")
    time = r.numbers("time", (None,))
    samples = len(time)
    if samples < MIN_SAMPLES:
        r.fail("time", f"{samples} samples: too short for an episode (at least {MIN_SAMPLES})")
    steps = np.diff(time)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0)) + 1
        r.fail(f"time[{k}]", f"{time[k]:.6g} s does not follow {time[k - 1]:.6g} s: times must increase")
    if time[0] < 0 or time[0] > MAX_PERIOD:
        r.fail("time[0]", f"{time[0]:.6g} s: a recording starts when the skill starts (0 s)")
    if np.median(steps) > MAX_PERIOD:
        r.fail("time", f"samples {np.median(steps):.3g} s apart: the fit needs at least {1 / MAX_PERIOD:g} per second")
    joints = r.numbers("joint_position", (None, None), time)
    if joints.shape[1] != N_JOINTS:
        r.fail("joint_position", f"{joints.shape[1]} joints, but the scenario's robot has {N_JOINTS}: a different robot")
    series = {"joint_position": joints,
              "object_position": r.numbers("object_position", (None, 3), time),
              "object_quaternion": r.numbers("object_quaternion", (None, 4), time)}
    if "tool_force" in r.arrays:
        series["tool_force"] = r.numbers("tool_force", (None,), time)
    if "joint_torque" in r.arrays:
        series["joint_torque"] = r.numbers("joint_torque", (None, N_JOINTS), time)
    for name, value in series.items():
        if len(value) != samples:
            r.fail(name, f"{len(value)} samples, but time has {samples}")
    norms = np.linalg.norm(series["object_quaternion"], axis=1)
    if np.any(np.abs(norms - 1) > 0.01):
        k = int(np.argmax(np.abs(norms - 1) > 0.01))
        r.fail(f"object_quaternion[{k}]", f"norm {norms[k]:.4g} (t = {time[k]:.3f} s): expected a unit quaternion")
    _check_joints(r, scn, joints, time)
    return Recording(
        path=str(path), robot=robot, time=_frozen(time),
        joint_position=_frozen(joints), object_position=_frozen(series["object_position"]),
        object_quaternion=_frozen(series["object_quaternion"] / norms[:, None]),
        parameters=_frozen(_parameters(r, task)), start_configuration=_frozen(_start_configuration(r, scn)),
        start_poses=_start_poses(r, scn),
        tool_force=_frozen(series["tool_force"]) if "tool_force" in series else None,
        joint_torque=_frozen(series["joint_torque"]) if "joint_torque" in series else None,
        source=r.text("source") if "source" in r.arrays else "",
    )


def _check_joints(r: _Reader, scn, joints: np.ndarray, time: np.ndarray) -> None:
    """Joint angles beyond the robot's limits (0.05 rad of slack): another robot's, or other units."""
    lower, upper = scn.robot.joint_limits
    outside = np.argwhere((joints < lower - 0.05) | (joints > upper + 0.05))
    if len(outside):
        k, j = (int(i) for i in outside[0])
        r.fail(f"joint_position[{k}, {j}]", f"{joints[k, j]:.4g} rad (t = {time[k]:.3f} s) is beyond joint {j + 1}'s "
                                            f"limits [{lower[j]:.3g}, {upper[j]:.3g}] rad: a different robot, or degrees?")


def _parameters(r: _Reader, task) -> np.ndarray:
    names = r.names("parameter_names")
    values = r.numbers("parameter_values", (len(names),))
    learnable = list(task.parameter_names)
    for name in names:
        if name not in learnable:
            r.fail("parameter_names", f"{quote(name)} is not a learnable parameter of the plan (learnable: "
                                      f"{listing(learnable)}): a recording of another skill or task")
    if len(set(names)) != len(names):
        r.fail("parameter_names", "a parameter is named twice")
    absent = [n for n in learnable if n not in names]
    if absent:
        r.fail("parameter_names", f"the value of {quote(absent[0])} is missing: every learnable parameter of the plan "
                                  "(the skill's run needs all)")
    by_name = dict(zip(names, values))
    ordered = np.array([by_name[n] for n in learnable])
    low, high = np.asarray(task.bounds[0], float), np.asarray(task.bounds[1], float)
    for k, name in enumerate(learnable):
        if not low[k] <= ordered[k] <= high[k]:
            r.fail("parameter_values", f"{name} = {ordered[k]:g} is outside the skill's bounds [{low[k]:g}, {high[k]:g}]")
    return ordered


def _start_configuration(r: _Reader, scn) -> np.ndarray:
    start = r.numbers("start_configuration", (N_JOINTS,))
    lower, upper = scn.robot.joint_limits
    if np.any(start < lower - 0.05) or np.any(start > upper + 0.05):
        j = int(np.argmax((start < lower - 0.05) | (start > upper + 0.05)))
        r.fail(f"start_configuration[{j}]", f"{start[j]:.4g} rad is beyond joint {j + 1}'s limits")
    return start


def _start_poses(r: _Reader, scn) -> dict:
    names = r.names("start_object_names")
    positions = r.numbers("start_positions", (len(names), 3))
    quaternions = r.numbers("start_quaternions", (len(names), 4))
    placed = sorted(n for n, o in scn.objects.items() if o.mjcf_body is not None)
    poses = {}
    for k, name in enumerate(names):
        if name not in placed:
            r.fail("start_object_names", f"{quote(name)} is no placed object of the scenario (placed: {listing(placed)})")
        norm = np.linalg.norm(quaternions[k])
        if abs(norm - 1) > 0.01:
            r.fail(f"start_quaternions[{k}]", f"norm {norm:.4g}: expected a unit quaternion")
        poses[name] = (_frozen(positions[k]), _frozen(quaternions[k] / norm))
    tracked = scn.calibration.tracked if scn.calibration is not None else None
    if tracked is not None and tracked not in poses:
        r.fail("start_object_names", f"the tracked object {quote(tracked)}'s start pose is missing")
    return poses


def write_npz(arrays: dict) -> bytes:
    """The ``.npz`` bytes of ``arrays`` (name -> array; text as numpy strings), compressed."""
    buffer = io.BytesIO()
    named: dict = {k: np.asarray(v) for k, v in arrays.items()}
    np.savez_compressed(buffer, **named)
    return buffer.getvalue()


__all__ = ["FORMAT", "OPTIONAL", "REQUIRED", "Recording", "read_recording", "write_npz"]
