"""The simulated MuJoCo model of a scenario: its MJCF scene with the scenario's gravity and
control period. Both engines, rendering and evaluation simulate this model."""

from __future__ import annotations

import mujoco


def load_model(scn) -> mujoco.MjModel:
    """The scenario's MJCF with its gravity and control period applied (one physics step per
    control step)."""
    model = mujoco.MjModel.from_xml_path(scn.scene)
    model.opt.timestep = 1.0 / scn.control_hz
    if not scn.gravity:
        model.opt.gravity[:] = 0.0
    return model
