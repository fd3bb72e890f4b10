"""The impedance controller's static settings and the arm's layout, shared by both engines: the
JAX law (``mjxskill.engine.mjx.controller``, over MJX) and the numpy one (``mjxskill.engine.native.controller``,
over native MuJoCo). Host-side only: nothing here imports MJX.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from mjxskill.errors import quote
from mjxskill.sim.scene import ARM_JOINTS, TOOL_SITE

COMMAND_SIZE = 19
N_ARM = 7
DEFAULT_STIFFNESS = (400.0, 400.0, 400.0, 50.0, 50.0, 50.0)  # SkiREIL default


class ControllerConfig(NamedTuple):
    """Static, host-side settings (hashable: fine as a closure constant or static argument)."""

    site_id: int  # MuJoCo id of the tool site
    site_body_id: int  # body the site is attached to
    torque_limit: tuple[float, ...]  # (7,) Nm, from the actuators' ctrlrange
    nullspace_stiffness: float = 5.0  # Nm/rad
    stiffness_rate: float = 500.0  # (N/m or Nm/rad) per second
    wrench_rate: float = 10.0  # N/s (Nm/s for the torque part)
    torque_step: float = 2.0  # Nm per control step
    dt: float = 0.002  # control period, s (= model timestep: one control step per mjx.step)
    pinv_damping: float = 1e-6  # lambda in (J J^T + lambda I)^-1

    @classmethod
    def from_model(cls, model: mujoco.MjModel, site: str = TOOL_SITE, **overrides) -> "ControllerConfig":
        """Reads ids and torque limits from ``model``; keyword ``overrides`` replace defaults."""
        dof = [int(model.jnt_dofadr[model.joint(j).id]) for j in ARM_JOINTS]
        if dof != list(range(N_ARM)):
            raise ValueError(f"arm joints must be the model's first 7 dofs, got dof addresses {dof}")
        site_id = int(model.site(site).id)
        limits = []
        for j in ARM_JOINTS:
            act = [a for a in range(model.nu) if model.actuator_trnid[a, 0] == model.joint(j).id]
            if len(act) != 1:
                raise ValueError(f"joint {quote(j)} needs exactly one torque actuator, found {len(act)}")
            limits.append(float(np.max(np.abs(model.actuator_ctrlrange[act[0]]))))
        kw = dict(dt=float(model.opt.timestep))
        kw.update(overrides)
        config = cls(site_id, int(model.site_bodyid[site_id]), tuple(limits), **kw)
        if not config.pinv_damping > 0:  # the compiled law's Cholesky pivots are >= sqrt(pinv_damping)
            raise ValueError(f"pinv_damping must be positive, got {config.pinv_damping!r}")
        return config


def rate_limit(previous, target, max_delta, xp):
    """``target`` approached from ``previous`` by at most ``max_delta`` per element (``xp``: the
    engine's array namespace, ``engine.common.arrays``): how the law ramps its stiffness and wrench
    (``stiffness_rate``, ``wrench_rate``) and its torque (``torque_step``). The numba kernel
    (``engine.native.kernels``) writes the same law per element, as compiled code must."""
    return previous + xp.clip(target - previous, -max_delta, max_delta)
