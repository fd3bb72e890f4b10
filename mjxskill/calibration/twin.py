"""The twin's physical values as ``mujoco.sysid`` parameters, and twins with other values.

``sysid_parameters`` makes one ``sysid.Parameter`` per entry of the scenario's ``calibration``
section, each with a modifier that writes its value into an ``MjSpec`` as ``build_model`` writes
the YAML's (``mjxskill.sim.model``): the mass and the centre of mass through sysid's own
``apply_body_mass_ipos`` (the inertia scaled with the mass, about the shape's centroid as the
YAML's is), the friction through ``write_friction`` (the object's geoms and every contact pair
touching them, a pair taking the larger of its two sides). sysid compiles the spec with the
candidate values (``apply_param_modifiers``), so the model the fit simulates is the one
``load_scenario`` would build from a YAML holding them.

``with_values`` is the same change made to a ``Scenario``: the "true" twin a test or the
benchmark records from, and the calibrated twin.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
from mujoco import sysid

from mjxskill.scenario.calibration import FIELDS, CalibrationParameter
from mjxskill.scenario.schema import Scenario, frozen_array, frozen_mapping
from mjxskill.sim.model import scenario_spec, write_friction


def _mass_modifier(body: str):
    def modify(spec: mujoco.MjSpec, param) -> None:
        sysid.model_modifier.apply_body_mass_ipos(spec, body, mass=float(param.value[0]), rot_inertia_scale=True)
    return modify


def _com_modifier(body: str, axis: int, centroid: float):
    def modify(spec: mujoco.MjSpec, param) -> None:
        ipos = np.array(spec.body(body).ipos, float)
        ipos[axis] = centroid + float(param.value[0])
        sysid.model_modifier.apply_body_mass_ipos(spec, body, ipos=ipos)
    return modify


def _friction_modifier(scn: Scenario, name: str):
    def modify(spec: mujoco.MjSpec, param) -> None:
        write_friction(spec, scn, {name: float(param.value[0])})
    return modify


def sysid_parameters(scn: Scenario, spec: mujoco.MjSpec | None = None):
    """A ``sysid.ParameterDict`` of the scenario's ``calibration.parameters`` (nominal: the YAML's
    values, bounds: the section's), each writing its value into a spec built by
    ``scenario_spec(scn)`` (``spec``, when given, is read for the shape's centroid)."""
    assert scn.calibration is not None
    spec = scenario_spec(scn) if spec is None else spec
    params = sysid.ParameterDict()
    for p in scn.calibration.parameters:
        body = scn.objects[p.object].mjcf_body
        assert body is not None  # calibration objects have a body (mjxskill.scenario.calibration)
        if p.field == "mass":
            modifier = _mass_modifier(body)
        elif p.field == "friction":
            modifier = _friction_modifier(scn, p.object)
        else:
            axis = p.axis
            assert axis is not None
            centroid = float(np.array(spec.body(body).ipos, float)[axis]) - p.nominal
            modifier = _com_modifier(body, axis, centroid)
        params.add(sysid.Parameter(p.key, p.nominal, p.bounds[0], p.bounds[1], modifier=modifier))
    return params


def with_values(scn: Scenario, values: dict[str, float], *, friction_range=False) -> Scenario:
    """``scn`` with the physical ``values`` (key "<object>.<field>" of ``FIELDS`` -> value) in
    place of its own, its model built again. ``friction_range``: the randomization's new
    per-world friction range ((low, high) or None), or False to keep it."""
    objects = dict(scn.objects)
    for key, value in values.items():
        name, _, field = key.partition(".")
        if field not in FIELDS or name not in objects:
            raise KeyError(f"{key!r}: expected '<object>.<field>' with a field of {sorted(FIELDS)}")
        obj = objects[name]
        if field.startswith("com_offset."):
            offset = np.array(obj.com_offset, float)
            offset["xyz".index(field[-1])] = value
            objects[name] = dataclasses.replace(obj, com_offset=frozen_array(offset))
        elif field == "mass":
            objects[name] = dataclasses.replace(obj, mass=float(value))
        else:
            objects[name] = dataclasses.replace(obj, friction=float(value))
    randomization = scn.randomization
    if friction_range is not False:
        randomization = dataclasses.replace(randomization, friction_range=friction_range)
    return dataclasses.replace(scn, objects=frozen_mapping(objects), randomization=randomization)


def parameter_values(scn: Scenario) -> dict[str, float]:
    """The scenario's current values of its ``calibration.parameters`` (key -> value)."""
    assert scn.calibration is not None
    out = {}
    for p in scn.calibration.parameters:
        obj = scn.objects[p.object]
        out[p.key] = float(obj.com_offset[p.axis]) if p.axis is not None else float(getattr(obj, p.field))
    return out


def finite_difference_steps(parameters: tuple[CalibrationParameter, ...], share: float) -> np.ndarray:
    """(n, 1) the fit's finite-difference step of each parameter: ``share`` of its bounds' width."""
    return np.array([[share * (p.bounds[1] - p.bounds[0])] for p in parameters])


__all__ = ["finite_difference_steps", "parameter_values", "sysid_parameters", "with_values"]
