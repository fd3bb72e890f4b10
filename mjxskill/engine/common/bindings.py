"""Host-side bindings between a scenario and its MJCF scene, computed once before tracing.

Every scenario object the rollout refers to at run time (leaf targets, reward targets, the
success test, randomized objects) gets a slot in a per-world table of nominal poses. How its
current pose is read depends on what the MJCF makes of it:

* ``FREE``: a body with a free joint (the pushed object): read from ``data.xpos/xquat``; its
  randomized start pose is written into ``qpos``.
* ``MOCAP``: a mocap body (the box with the hole, the goal marker): it never moves during an
  episode; its randomized pose is written into ``data.mocap_pos/mocap_quat``.
* ``NOMINAL``: no body (a named pose) or a body fixed to the robot that nothing reads: the
  randomized nominal pose itself.

These are static Python ints baked into the trace (Brax/Playground style).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from mjxskill.scenario.schema import Scenario
from mjxskill.sim.tool_force import tool_force_addresses

FREE, MOCAP, NOMINAL = 0, 1, 2


@dataclass(frozen=True)
class ObjectSlot:
    """How to read one scenario object's pose.

    name: scenario object name. how: FREE, MOCAP or NOMINAL. body_id: MuJoCo body id (-1 when
    NOMINAL). qpos_adr: first qpos address of the free joint (-1 unless FREE). mocap_id: index in
    ``data.mocap_pos`` (-1 unless MOCAP). position (3,), quat (4,): nominal pose from the YAML.
    """

    name: str
    how: int
    body_id: int
    qpos_adr: int
    mocap_id: int
    position: tuple[float, ...]  # (3,)
    quat: tuple[float, ...]  # (4,)


@dataclass(frozen=True)
class SceneBindings:
    """Static facts about the scene the rollout needs.

    slots: one per referenced scenario object; ``slot_of`` maps names to indices.
    arm_qpos: (7,) qpos addresses of the arm joints (0..6 in our scenes).
    randomized_pairs: contact pair ids whose friction follows the world's friction sample.
    force_sensors: ``sensordata`` addresses of the tool's touch sensors; their sum is the
    measured contact force (``mjxskill.sim.tool_force``).
    """

    slots: tuple[ObjectSlot, ...]
    slot_of: dict
    arm_qpos: tuple[int, ...]
    randomized_pairs: tuple[int, ...]
    force_sensors: tuple[int, ...]

    def __hash__(self):
        return hash((self.slots, self.arm_qpos, self.randomized_pairs, self.force_sensors))


def referenced_objects(scn: Scenario, leaf_object_names) -> list[str]:
    """Scenario objects the rollout reads, in a stable order (first mention)."""
    names: list[str] = []

    def add(name):
        if name and name not in names:
            names.append(name)

    for name in leaf_object_names:
        add(name)
    for reward in scn.rewards:
        add(reward.object)
        add(reward.target)
    add(scn.success.object)
    add(scn.success.target)
    for name in scn.randomization.xy_sigma:
        add(name)
    return names


def bind_scene(scn: Scenario, model: mujoco.MjModel, object_names) -> SceneBindings:
    slots = []
    for name in object_names:
        obj = scn.objects[name]
        body = obj.mjcf_body
        body_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body) if body else -1
        how, qpos_adr, mocap_id = NOMINAL, -1, -1
        if body_id >= 0:
            jnt = int(model.body_jntadr[body_id])
            if model.body_mocapid[body_id] >= 0:
                how, mocap_id = MOCAP, int(model.body_mocapid[body_id])
            elif jnt >= 0 and model.jnt_type[jnt] == mujoco.mjtJoint.mjJNT_FREE:
                how, qpos_adr = FREE, int(model.jnt_qposadr[jnt])
        slots.append(
            ObjectSlot(
                name=name,
                how=how,
                body_id=body_id if how != NOMINAL else -1,
                qpos_adr=qpos_adr,
                mocap_id=mocap_id,
                position=tuple(float(v) for v in obj.pose.position),
                quat=tuple(float(v) for v in obj.pose.quat),
            )
        )
    arm = tuple(int(model.jnt_qposadr[model.joint(f"joint{i}").id]) for i in range(1, 8))
    # Friction randomization applies to the contact pairs that touch a randomized free object.
    randomized_bodies = {s.body_id for s in slots if s.how == FREE and s.name in scn.randomization.xy_sigma}
    pairs = tuple(
        p
        for p in range(model.npair)
        if model.geom_bodyid[model.pair_geom1[p]] in randomized_bodies
        or model.geom_bodyid[model.pair_geom2[p]] in randomized_bodies
    )
    return SceneBindings(
        slots=tuple(slots),
        slot_of={s.name: i for i, s in enumerate(slots)},
        arm_qpos=arm,
        randomized_pairs=pairs,
        force_sensors=tool_force_addresses(model),
    )


def nominal_poses(bindings: SceneBindings) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) positions and (K, 4) quaternions of the slots as the YAML places them."""
    pos = np.array([s.position for s in bindings.slots], dtype=np.float32).reshape(-1, 3)
    quat = np.array([s.quat for s in bindings.slots], dtype=np.float32).reshape(-1, 4)
    return pos, quat
