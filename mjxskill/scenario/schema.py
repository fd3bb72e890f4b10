"""The scenario (digital twin) as immutable values: what ``load_scenario`` returns.

Everything here is frozen: dataclasses are ``frozen=True``, sequences are tuples, name-keyed
tables are ``MappingProxyType`` and arrays are numpy arrays with ``writeable=False``.

Conventions (the same in the YAML files under ``assets/scenarios/``):

* Lengths in m, angles in the YAML in degrees (``rpy_deg``), joint angles in rad, forces in N,
  torques in Nm, stiffness in N/m (translational) and Nm/rad (rotational).
* World frame: robot base at the origin, z up, table top at z = 0.
* A pose is ``position`` (3,) m plus ``rpy_deg`` (3,) = roll, pitch, yaw in degrees about the
  fixed world axes x, y, z (extrinsic "xyz": R = Rz(yaw) Ry(pitch) Rx(roll)); ``quat`` gives the
  same rotation as a (4,) quaternion (w, x, y, z), MuJoCo's order.
* Names of objects, poses and the robot are PDDL objects; PDDL is case-insensitive, so the
  generated PDDL uses ``pddl_name`` = the name in lower case, and names must differ in more than
  case.
* Classes holding arrays compare and hash by identity (``eq=False``), so a Scenario can be a
  static argument of ``jax.jit``.
* Objectives are maximized: every reward is a "more is better" term times its weight, so
  penalties (applied wrench) carry negative weights.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Mapping

import numpy as np

from mjxskill.errors import quote
from mjxskill.scenario.vocabulary import REQUIRED, REWARD_KINDS

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario.calibration import Calibrated, Calibration


# Bounds of the run settings a scenario gives defaults for, shared with the command-line flags
# and a run's config.yaml (mjxskill.runs.settings): one number, one place.
MAX_EPISODE_SECONDS = 3600.0  # an hour of simulated time; the shipped episodes last 12 and 18 s
MAX_SEED = 2**32 - 1  # seeds become uint32 PRNG keys and numpy seed words
MIN_N_INIT = 2  # the optimizer's warm-up needs two points to fit a model
# Upper bounds on what sizes the work, each far beyond any run we know of, so that a typo (an
# extra zero or three) is refused before a run directory is written instead of exhausting the
# machine after it (--repeats 100000 wrote 20,908 seed folders in a minute; --worlds 100000 and
# --batch-size 10**9 died allocating after the directory existed; --budget 10**12 grew memory).
# The episodes of one call (batch x worlds) are bounded with every command's, against the machine's
# memory too: mjxskill.runs.bounds.MAX_CALL_EPISODES and call_episodes_problem.
MAX_BUDGET = 100_000  # evaluations per run; the paper's runs have 400, the GP is cubic in them
MAX_BATCH = 4096  # parameter sets per batch
MAX_WORLDS = 4096  # randomized worlds per parameter set; the paper uses 7
MAX_REPEATS = 1000  # repetitions of a run or an experiment (one folder each); the paper has 10


def frozen_array(values, dtype=np.float64) -> np.ndarray:
    """A read-only copy of ``values``."""
    array = np.array(values, dtype=dtype)
    array.flags.writeable = False
    return array


def frozen_mapping(items) -> Mapping:
    return MappingProxyType(dict(items))


@dataclass(frozen=True, eq=False)
class Pose:
    """position: (3,) m in the world frame. rpy_deg: (3,) deg, extrinsic x-y-z (see module doc)."""

    position: np.ndarray
    rpy_deg: np.ndarray

    @property
    def quat(self) -> np.ndarray:
        """(4,) unit quaternion (w, x, y, z) of ``rpy_deg``."""
        # lazy: scipy.spatial costs ~0.25 s, and every command's bad-input errors load a scenario
        from scipy.spatial.transform import Rotation

        x, y, z, w = Rotation.from_euler("xyz", self.rpy_deg, degrees=True).as_quat()
        return frozen_array([w, x, y, z])

    @property
    def yaw(self) -> float:
        """Rotation about world z in rad (the planar tasks' orientation)."""
        return float(np.deg2rad(self.rpy_deg[2]))


@dataclass(frozen=True, eq=False)
class WorldObject:
    """An object or a named pose of the world model.

    type: PDDL type (a key of ``Scenario.types``). mjcf_body: body name in the scene's MJCF
    (None for abstract poses and for geoms of the world body). mjcf_geom: a geom of the MJCF's
    world body the object is (the table), when it has no body. shape: one of ``mjxskill.scenario.vocabulary.SHAPES``. size:
    shape-specific (m, ``SHAPES``). mass (kg), com_offset (3,) m (centre of mass relative to the
    shape's centroid, in the body frame), friction (sliding coefficient) and size are the
    simulated physics: ``mjxskill.sim.model.build_model`` writes them into the MJCF model; None
    (or zeros for com_offset) leaves the MJCF's value. approach_offset: (3,) m, world-frame
    offset from ``pose.position`` of the object's approach pose (where a skill's tree takes
    the tool, ``$object.approach_offset``). extra: the shape's further constants (``SHAPES``).
    relations: PDDL facts about the object in the initial state, e.g. "(pushable triangle-1)".
    """

    name: str
    type: str
    pose: Pose
    mjcf_body: str | None
    shape: str
    size: np.ndarray
    mass: float | None
    friction: float | None
    com_offset: np.ndarray
    approach_offset: np.ndarray
    extra: Mapping[str, float]
    relations: tuple[str, ...]
    mjcf_geom: str | None = None

    @property
    def pddl_name(self) -> str:
        return self.name.lower()


@dataclass(frozen=True, eq=False)
class Robot:
    """The arm.

    start_configs: (n, 7) rad, sampled uniformly per training world. eval_configs: (m, 7) rad,
    the unseen ones used only for evaluation. home: (7,) rad. joint_limits: (2, 7) rad.
    nullspace_stiffness: Nm/rad toward the start posture. default_stiffness: (6,) N/m x3,
    Nm/rad x3, used when no skill sets one. tool_site: MJCF site at the tool tip.
    relations: initial PDDL facts about the robot.
    """

    name: str
    type: str
    tool_site: str
    home: np.ndarray
    joint_limits: np.ndarray
    start_configs: np.ndarray
    eval_configs: np.ndarray
    nullspace_stiffness: float
    default_stiffness: np.ndarray
    relations: tuple[str, ...]

    @property
    def pddl_name(self) -> str:
        return self.name.lower()


@dataclass(frozen=True)
class SkillParameter:
    """One parameter of a skill.

    plan: True when the planner grounds it (a PDDL action argument; ``type`` is then a PDDL type);
    otherwise ``type`` is "float" or "vector" and ``default`` its value. learnable: left open by
    the plan and searched by the optimizer within ``bounds`` = (lower, upper).
    """

    name: str
    type: str
    plan: bool
    unit: str = ""
    default: float | tuple[float, ...] | None = None
    bounds: tuple[float, float] | None = None
    learnable: bool = False
    description: str = ""


@dataclass(frozen=True)
class Skill:
    """A skill of the library: PDDL action plus its behavior tree.

    parameters: in declaration order; the ``plan`` ones are the PDDL action's arguments in that
    order. preconditions / holdconditions / postconditions: PDDL literals over ``?argument``
    variables; hold-conditions must hold while the skill runs, so they become preconditions in
    PDDL; negated postconditions are delete effects. tree: the skill's eBT as a template over
    the primitive library (``mjxskill.ebt.template``), filled in per planned use
    (``mjxskill.ebt.from_plan``).
    """

    name: str
    parameters: tuple[SkillParameter, ...]
    preconditions: tuple[str, ...]
    holdconditions: tuple[str, ...]
    postconditions: tuple[str, ...]
    tree: object = None

    @property
    def pddl_name(self) -> str:
        return self.name.lower()

    @property
    def arguments(self) -> tuple[SkillParameter, ...]:
        return tuple(p for p in self.parameters if p.plan)

    def parameter(self, name: str) -> SkillParameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"skill {self.name} has no parameter {quote(name)}")

    def value(self, name: str):
        """Default value of a fixed (non-plan) parameter."""
        return self.parameter(name).default


@dataclass(frozen=True, eq=False)
class Reward:
    """One reward term.

    task_completion: ``value`` per step while the BT has returned SUCCESS.
    ee_distance_to_box: 1 / (w (d + d_o)), d = tool to ``target`` distance (m).
    applied_wrench: min(|Fx| + |Fy| + |Fz|, cap) of the commanded force (N); use a negative
    weight. The cap bounds the worst value, which a diverged world receives.
    contact_force: min(F, cap), F the measured normal contact force between the tool (or the
    item it holds) and everything else, N, averaged over the tick's control steps: summed over
    the episode, the accumulated force (its peak is the metric ``peak_contact_force``); use a
    negative weight.
    exp_*: exp(-(d_m + d_o) / (2 sigma_w^2)) with d_m the tool-to-``target`` distance
    (exp_ee_to_goal), the tool reference-to-actual distance (exp_ee_to_reference) or
    position_weight * |p_obj - p_target| + orientation_weight * |angle (rad)| between ``object``
    and ``target`` (object_pose_divergence). Target points are ``target``'s position plus
    ``target_offset`` (world frame).
    """

    name: str
    kind: str
    weight: float
    objective: str
    constants: Mapping[str, float]
    object: str | None = None
    target: str | None = None
    target_offset: np.ndarray | None = None  # (3,) m added to the target's position

    def constant(self, key: str) -> float:
        """The constant ``key``: the YAML's value, or the kind's default (``REWARD_KINDS``)."""
        if key in self.constants:
            return float(self.constants[key])
        default = REWARD_KINDS[self.kind].constants.get(key, REQUIRED)
        if default is REQUIRED:
            raise KeyError(f"reward {quote(self.name)} ({self.kind}) has no constant {quote(key)}")
        return float(default)


@dataclass(frozen=True, eq=False)
class Success:
    """The task's success test, checked at the end of the episode.

    kind "object_at_pose": ``object`` within ``position_tolerance`` m (in the x-y plane) and
    ``orientation_tolerance_deg`` of ``target``. kind "inserted": the tool tip inside the hole of
    ``target`` (a box_with_hole: the hole's footprint, in the box's frame) deeper than ``depth`` m
    below its opening; ``object`` is the inserted item. kind "object_in_region": ``object``'s
    position inside the box ``region_size`` (3,) m centred at ``region_center`` (3,) m in
    ``target``'s frame, and (when given) within ``orientation_tolerance_deg`` of ``target``.
    """

    kind: str
    object: str
    target: str
    position_tolerance: float | None = None
    orientation_tolerance_deg: float | None = None
    depth: float | None = None
    region_size: np.ndarray | None = None
    region_center: np.ndarray | None = None


@dataclass(frozen=True)
class Randomization:
    """Domain randomization of one evaluation world.

    xy_sigma: object/pose name -> standard deviation (m) of a Gaussian x, y offset.
    clip_sigmas: offsets clipped to +- clip_sigmas * sigma (None, the YAML leaving it out: not
    clipped, the paper's Gaussian; SkiREIL's code clipped at 1.0).
    friction_range: (low, high) uniform friction of the randomized objects, or None.
    n_worlds: worlds per parameter set; the robot start configuration is drawn uniformly from
    ``Robot.start_configs``.
    """

    xy_sigma: Mapping[str, float]
    clip_sigmas: float | None
    friction_range: tuple[float, float] | None
    n_worlds: int


@dataclass(frozen=True)
class Optimizer:
    budget: int  # evaluations (parameter sets) per run
    batch_size: int  # parameter sets per batch
    n_init: int  # uniform random warm-up evaluations
    seed: int
    repetitions: int  # independent runs in the paper's experiments


@dataclass(frozen=True)
class PickBound:
    """The YAML's ``pick``: the bound on the commanded force (``peak_commanded_force``, N) within
    which an experiment and ``evaluate`` pick one solution per run, and why that number (the
    report states both). A command's ``--max-force`` overrides it."""

    max_force: float
    why: str


@dataclass(frozen=True)
class ManualSet:
    """An operator's parameter set from the YAML's ``manual_parameters``.

    values: learnable parameter name (e.g. "Slide.offset_x_start") -> value, checked against the
    skill's bounds when loaded. where: the set's place in the file (for errors found when a plan
    is matched with it, see ``mjxskill.task``).
    """

    values: Mapping[str, float]
    where: str


@dataclass(frozen=True)
class ParameterPrior:
    """An operator's belief about one learnable parameter, from the YAML's ``parameter_priors``:
    good values lie near ``mean`` (inside the parameter's bounds), ``std`` > 0 in the
    parameter's unit; a Gaussian truncated to the bounds (``mjxskill.gp.Prior``). where: the
    entry's place in the file."""

    mean: float
    std: float
    where: str


@dataclass(frozen=True, eq=False)
class Scenario:
    """A validated scenario: the world model and the task settings, no plan (``mjxskill.task``
    plans a goal in it). See the module docstring for units and frames.

    name: "push" / "peg". source: the YAML file. libraries: the skill library files it includes
    (``skill_library``). scene: the MJCF file. gravity: False runs the
    scene without gravity (SkiREIL's peg). types: PDDL type -> parent type (None: root).
    predicates: name -> argument types. objects: name -> WorldObject (poses included).
    skills: name -> Skill. goal: the default goal. manual_parameters: name -> ManualSet, the
    operators' parameter sets (illustrative values). locations: key path -> "file: key path
    (line N)" of the entries checked after loading (the goal, when it is planned; the scene
    references), so that those errors name the file, key and line too (``where``).
    parameter_priors: learnable parameter name ("<skill>.<parameter>") -> ParameterPrior, where
    the operator believes good values lie (the optimizer's prior, ``mjxskill.training.priors``).
    pick: the pick's force bound and its reason (None: the scenario states none, and a pick
    without ``--max-force`` is unbounded). calibration: what ``python -m mjxskill.calibrate``
    may fit to recordings (``mjxskill.scenario.calibration``; None: nothing); calibrated: what a
    fit wrote into this scenario (None: not a fitted one).
    """

    name: str
    source: str
    scene: str
    gravity: bool
    episode_seconds: float
    bt_hz: int
    control_hz: int
    types: Mapping[str, str | None]
    predicates: Mapping[str, tuple[str, ...]]
    objects: Mapping[str, WorldObject]
    robot: Robot
    skills: Mapping[str, Skill]
    goal: str
    rewards: tuple[Reward, ...]
    objective_names: tuple[str, ...]
    success: Success
    randomization: Randomization
    optimizer: Optimizer
    manual_parameters: Mapping[str, ManualSet]
    locations: Mapping[str, str] = field(default_factory=lambda: MappingProxyType({}))
    libraries: tuple[str, ...] = ()
    parameter_priors: Mapping[str, ParameterPrior] = field(default_factory=lambda: MappingProxyType({}))
    pick: PickBound | None = None
    calibration: "Calibration | None" = None
    calibrated: "Calibrated | None" = None

    def where(self, key_path: str) -> str:
        """``"file: key path (line N)"`` of a YAML entry (the file alone when not recorded)."""
        return self.locations.get(key_path, self.source)

    @property
    def episode_ticks(self) -> int:
        """BT ticks per episode."""
        return int(round(self.episode_seconds * self.bt_hz))

    @property
    def steps_per_tick(self) -> int:
        """Control steps per BT tick."""
        return self.control_hz // self.bt_hz

    def object_by_pddl_name(self, pddl_name: str) -> WorldObject | Robot:
        candidates: tuple[WorldObject | Robot, ...] = (*self.objects.values(), self.robot)
        for obj in candidates:
            if obj.pddl_name == pddl_name.lower():
                return obj
        raise KeyError(pddl_name)
