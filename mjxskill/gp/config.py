"""The optimizer's problem and settings (``MOBOConfig``), and reading them back from a state
file's JSON (``config_from_json``; ``optimizer.save_state`` writes it).
"""

from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np

from mjxskill.errors import quote
from mjxskill.gp.prior import Prior, prior_of
from mjxskill.gp.settings import AcquisitionSettings, acquisition_defaults, acquisition_settings

STATE_FORMAT = "mjxskill.gp.MOBOState/2"
OLD_FORMAT = "mjxskill.gp.MOBOState/1"  # flat config: acquisition settings beside the problem


@dataclasses.dataclass(frozen=True)
class MOBOConfig:
    """Problem and optimizer settings (immutable, JSON-serializable).

    bounds: (2, d) lower and upper bounds (any nested sequence; stored as tuples).
    acquisition: the model and acquisition settings (validated by their own class); a
    mapping is accepted and read by :func:`acquisition_settings` over the defaults; None:
    the defaults, ``acquisition_defaults(reference_given=..., n_objectives=...)`` (a given
    reference point takes more hypervolume directions, settings.GIVEN_REFERENCE_DEFAULTS, and with
    three objectives the closed-form improvement: GIVEN_REFERENCE_THREE_OBJECTIVES_BY_GENERATION).
    ref_point: (m,) reference point of the hypervolume scalarizations in objective units
    (minimized), e.g. the one the run's hypervolume is reported against; None infers it
    (``acquisition.reference``: from the warm-up, or the observed front at each proposal).
    prior: where good parameter values are believed to lie (``Prior``, or its ``to_dict``
    mapping), checked against the bounds; None: no prior (uniform warm-up, plain acquisition).
    """

    bounds: tuple
    n_objectives: int
    batch_size: int = 8
    n_init: int = 40
    seed: int = 0
    acquisition: AcquisitionSettings | None = None
    ref_point: tuple | None = None
    prior: Prior | None = None

    def __post_init__(self):
        b = np.asarray(self.bounds, dtype=np.float64)
        if b.ndim != 2 or b.shape[0] != 2 or b.shape[1] < 1:
            raise ValueError(f"MOBOConfig.bounds: expected shape (2, d), got {b.shape}")
        if not np.all(np.isfinite(b)):
            raise ValueError(f"MOBOConfig.bounds: must be finite, got {b.tolist()}")
        bad = np.flatnonzero(b[0] >= b[1])
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"MOBOConfig.bounds: lower >= upper in dimension {i} ({b[0, i]} >= {b[1, i]})"
            )
        object.__setattr__(self, "bounds", tuple(tuple(float(v) for v in row) for row in b))
        for name in ("n_objectives", "batch_size"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
                raise ValueError(f"MOBOConfig.{name}: expected a positive integer, got {quote(v)}")
        if not isinstance(self.n_init, (int, np.integer)) or self.n_init < 2:
            raise ValueError(f"MOBOConfig.n_init: need at least 2 warm-up points, got {quote(self.n_init)}")
        if self.ref_point is not None:
            r = np.asarray(self.ref_point, dtype=np.float64)
            if r.shape != (self.n_objectives,) or not np.all(np.isfinite(r)):
                raise ValueError(f"MOBOConfig.ref_point: expected {self.n_objectives} finite numbers, got {quote(self.ref_point)}")
            object.__setattr__(self, "ref_point", tuple(float(v) for v in r))
        defaults = acquisition_defaults(reference_given=self.ref_point is not None, n_objectives=self.n_objectives)
        if self.acquisition is None:
            object.__setattr__(self, "acquisition", defaults)
        elif isinstance(self.acquisition, Mapping):
            object.__setattr__(self, "acquisition", acquisition_settings(self.acquisition, defaults))
        elif not isinstance(self.acquisition, AcquisitionSettings):
            raise ValueError(f"MOBOConfig.acquisition: expected AcquisitionSettings or a mapping, got {quote(self.acquisition)}")
        try:
            object.__setattr__(self, "prior", prior_of(self.prior))
            if self.prior is not None:
                self.prior.check_bounds(self.bounds)
        except ValueError as err:
            raise ValueError(f"MOBOConfig.prior: {err}") from None

    @property
    def dim(self) -> int:
        return len(self.bounds[0])

    def to_dict(self) -> dict:
        """Plain JSON-able form: the acquisition settings nested as a mapping."""
        assert self.acquisition is not None  # __post_init__ sets it
        return {**{f.name: getattr(self, f.name) for f in dataclasses.fields(self)}, "acquisition": self.acquisition.to_dict(),
                "prior": None if self.prior is None else self.prior.to_dict()}


_PROBLEM_FIELDS = ("bounds", "n_objectives", "batch_size", "n_init", "seed")


def config_from_json(meta, path) -> MOBOConfig:
    """The config of a state file: format 2 (nested acquisition) or 1 (flat, converted)."""
    if not isinstance(meta, dict) or meta.get("format") not in (STATE_FORMAT, OLD_FORMAT):
        raise ValueError(f"load_state: {path} is not an mjxskill optimizer state")
    raw = dict(meta["config"])
    if meta["format"] == OLD_FORMAT:
        # Format 1 wrote every acquisition field beside the problem fields: regroup them.
        raw = {**{k: raw.pop(k) for k in _PROBLEM_FIELDS if k in raw}, "acquisition": raw}
    unknown = set(raw) - {f.name for f in dataclasses.fields(MOBOConfig)}
    if unknown:
        raise ValueError(f"load_state: {path} has unknown config fields {sorted(unknown)}")
    if isinstance(raw.get("acquisition"), dict) and "hypervolume_improvement" not in raw["acquisition"]:
        # Written before the closed form existed: that state estimated it over directions
        # (today's defaults for three objectives and a given reference point would not).
        raw["acquisition"] = {**raw["acquisition"], "hypervolume_improvement": "directions"}
    try:
        return MOBOConfig(**raw)
    except ValueError as err:
        raise ValueError(f"load_state: {path}: {err}") from None
