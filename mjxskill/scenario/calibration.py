"""The scenario's ``calibration`` section: which physical values of the twin ``python -m
mjxskill.calibrate`` may fit to a robot's recordings, in which bounds, and the sensors' noise;
and ``calibrated``, what a fit wrote into the scenario it made (values, intervals, sources).

    calibration:
      tracked: ObjectToBePushed-1          # the object whose pose the recordings hold
      parameters:                          # "<object>.<field>": [lower, upper]
        ObjectToBePushed-1.mass: [1.0, 5.0]                # kg
        ObjectToBePushed-1.friction: [0.05, 0.6]
        ObjectToBePushed-1.com_offset.x: [-0.06, 0.06]     # m, in the body frame
      noise:                               # one standard deviation of each recorded signal
        joint_position: 5.0e-5             # rad
        object_position: 0.001             # m
        object_orientation_deg: 0.5        # deg
        tool_force: 0.5                    # N

The fields a parameter may name are ``FIELDS``: the object's ``mass``, its ``friction`` and one
coordinate of its ``com_offset``; the object must give the value in the YAML (the fit starts
there: ``python -m mjxskill.calibrate`` refuses bounds that do not hold it, ``outside``). The noise weighs the signals against each other in the fit
(each residual in units of its signal's noise); its overall scale does not change the fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Mapping

from mjxskill.errors import listing, quote
from mjxskill.scenario.domain import FRICTION, MASS, Domain
from mjxskill.scenario.fields import Field

_COM = Domain(-1.0, 1.0, unit="m", why="a centre of mass within a metre of the shape's centroid")
# field -> (unit, the domain of its bounds: the world model's own for mass and friction)
FIELDS = {
    "mass": ("kg", MASS),
    "friction": ("", FRICTION),
    "com_offset.x": ("m", _COM),
    "com_offset.y": ("m", _COM),
    "com_offset.z": ("m", _COM),
}
# signal -> (unit, default standard deviation, why that default)
NOISE = {
    "joint_position": ("rad", 5e-5, "an arm's joint encoders after their filter"),
    "object_position": ("m", 1e-3, "a motion-capture or marker tracker at about a metre"),
    "object_orientation_deg": ("deg", 0.5, "the same tracker's orientation"),
    "tool_force": ("N", 0.5, "a wrist force sensor, or the arm's estimate of the external force"),
}
NOISE_DOMAIN = Domain(0.0, 1e3, exclusive_minimum=True, why="a sensor's standard deviation")
CONFIDENCE = Domain(0.0, 1.0, exclusive_minimum=True, why="a probability")


@dataclass(frozen=True)
class CalibrationParameter:
    """One value the fit may change: ``key`` "<object>.<field>" (``FIELDS``), its ``bounds``
    (lower, upper) in ``unit``, its ``nominal`` value (the YAML's), ``where`` the entry's place
    in the file."""

    key: str
    object: str
    field: str
    bounds: tuple[float, float]
    nominal: float
    unit: str
    where: str

    @property
    def axis(self) -> int | None:
        """0, 1, 2 for a ``com_offset`` coordinate, else None."""
        return "xyz".index(self.field[-1]) if self.field.startswith("com_offset.") else None


@dataclass(frozen=True)
class Calibration:
    """The ``calibration`` section: the ``tracked`` object, the ``parameters`` in file order,
    the ``noise`` (signal -> standard deviation, ``NOISE``'s defaults filled in)."""

    tracked: str
    parameters: tuple[CalibrationParameter, ...]
    noise: Mapping[str, float]
    where: str


@dataclass(frozen=True)
class Calibrated:
    """The ``calibrated`` section a fit writes: parameter key -> (value, low, high) of its
    ``confidence`` interval, and the files it was fitted from (``sources``)."""

    values: Mapping[str, tuple[float, float, float]]
    confidence: float
    sources: tuple[str, ...]


def nominal_value(obj, field: str) -> float | None:
    """The YAML's value of ``field`` (``FIELDS``) of the WorldObject ``obj`` (None: not given)."""
    if field.startswith("com_offset."):
        return float(obj.com_offset["xyz".index(field[-1])])
    value = getattr(obj, field)
    return None if value is None else float(value)


def outside(calibration: Calibration) -> str | None:
    """Why the fit cannot start from the YAML's values (the first parameter whose bounds do not
    hold its value, located), or None."""
    for p in calibration.parameters:
        if not p.bounds[0] <= p.nominal <= p.bounds[1]:
            unit = f" {p.unit}" if p.unit else ""
            return (f"{p.where}: the bounds [{p.bounds[0]:g}, {p.bounds[1]:g}] do not hold the YAML's value "
                    f"{p.nominal:g}{unit} of objects.{p.object}.{p.field.partition('.')[0]}, where the fit starts")
    return None


def calibration(field: Field | None, objects) -> Calibration | None:
    """``calibration`` (None when the scenario has none); ``objects``: name -> WorldObject."""
    if field is None:
        return None
    f = field.mapping(required=("tracked", "parameters"), optional=("noise",))
    tracked = f["tracked"].string()
    movable = sorted(name for name, o in objects.items() if o.mjcf_body is not None and o.shape != "pose")
    if tracked not in movable:
        f["tracked"].fail(f"{quote(tracked)} is not an object with a body (objects with one: {listing(movable)})")
    parameters = []
    for key, item in f["parameters"].items():
        name, _, what = key.partition(".")
        if name not in objects:
            item.fail(f"{quote(key)} names no object (objects: {listing(sorted(objects))}); a parameter is "
                      "'<object>.<field>'")
        if what not in FIELDS:
            item.fail(f"{quote(key)}: the fit can change {listing(FIELDS)} of an object, not {quote(what)}")
        unit, domain = FIELDS[what]
        nominal = nominal_value(objects[name], what)
        if nominal is None:
            item.fail(f"objects.{name} gives no {what}: the fit starts from the YAML's value, so give one")
        low, high = item.vector(2, domain)
        if not low < high:
            item.fail(f"expected bounds [lower, upper] with lower < upper, got [{low:g}, {high:g}]")
        parameters.append(CalibrationParameter(key, name, what, (low, high), nominal, unit, item.where()))
    if not parameters:
        f["parameters"].fail("no parameter to fit: name at least one ('<object>.<field>': [lower, upper])")
    noise = {k: default for k, (_, default, _) in NOISE.items()}
    if "noise" in f:
        for key, item in f["noise"].mapping(optional=tuple(NOISE)).items():
            noise[key] = item.number(NOISE_DOMAIN)
    return Calibration(tracked, tuple(parameters), MappingProxyType(noise), field.where())


def calibrated(field: Field | None) -> Calibrated | None:
    """``calibrated`` (None when absent): ``values`` (key -> {value, low, high}), ``confidence``
    and ``sources`` (what the values were fitted from)."""
    if field is None:
        return None
    f = field.mapping(required=("values", "confidence", "sources"), optional=("report", "command"))
    values = {}
    for key, item in f["values"].items():
        v = item.mapping(required=("value", "low", "high"), optional=("nominal", "unit"))
        value, low, high = (v[k].number() for k in ("value", "low", "high"))
        if not low <= value <= high:
            item.fail(f"expected low <= value <= high, got {low:g}, {value:g}, {high:g}")
        values[key] = (value, low, high)
    for key in ("report", "command"):
        if key in f:
            f[key].string()
    return Calibrated(MappingProxyType(values), f["confidence"].number(CONFIDENCE), f["sources"].strings())


__all__ = ["FIELDS", "NOISE", "Calibrated", "Calibration", "CalibrationParameter", "calibrated", "calibration",
           "nominal_value", "outside"]
