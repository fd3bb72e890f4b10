"""The acquisition settings: one frozen, validated, hashable object.

``AcquisitionSettings`` holds everything that shapes a model-based proposal (models, fits,
acquisition search, padding); ``MOBOConfig.acquisition`` carries one. It is a static argument
of the jitted proposal, so it must stay hashable (a frozen dataclass of scalars and strings).

``acquisition_settings({"n_raw": 256, "model": "hybrid"})`` builds one from the flat
``{name: number | string}`` mapping that ``train --optimizer-option KEY=VALUE`` stores; every
check lives in ``__post_init__`` so that the constructor, that function and ``load_state``
validate the same way.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Mapping

# Allowed values of the string settings (first: what each choice means is in proposal.py).
CHOICES = {
    "model": ("hybrid", "scalarized", "per_objective"),
    "ei": ("draws", "moments"),
}


@dataclasses.dataclass(frozen=True)
class AcquisitionSettings:
    """Settings of the model-based proposal (hashable: part of the compile cache key)."""

    alpha: float = 0.05  # augmented Chebyshev coefficient
    bucket: int = 64  # training sets are padded to a multiple of this many rows (one compile per bucket)
    n_raw: int = 1024  # random candidates scored per batch element
    n_restarts: int = 10  # best candidates refined by projected Adam
    n_opt_steps: int = 100
    learning_rate: float = 0.02  # unit-cube coordinates per Adam step
    fit_starts: int = 2
    fit_steps: int = 50
    # One GP fit per batch element while the padded training set has at most this many
    # rows, one shared fit above (a fit costs O(n^3), q of them dominate the proposal time).
    per_element_fit_max_rows: int = 128
    # Hyperparameters are fitted on a random subset of at most this many real rows (the
    # posterior still conditions on all of them): a fit on 448 rows took ~4 s on 2 cores.
    fit_max_rows: int = 128
    # Which model each batch element uses (see proposal.py): "scalarized" (a GP on the
    # element's scalarization), "per_objective" (a GP per objective, scalarized draws),
    # "hybrid" (the first ceil(q/2) elements scalarized, the rest per-objective).
    model: str = "hybrid"
    n_draws: int = 128  # quasi-random posterior draws per point (per-objective model)
    # Per-objective acquisition: "draws" (quasi-MC log-EI) or "moments" (log-EI of the
    # moment-matched Gaussian); tau is the softplus width of "draws" (normalized units).
    ei: str = "draws"
    tau: float = 1e-3

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.type == "int":
                if not isinstance(v, int) or isinstance(v, bool):
                    raise ValueError(f"acquisition setting {f.name}: expected an integer, got {v!r}")
                if v < 1:
                    raise ValueError(f"acquisition setting {f.name}: expected a positive integer, got {v!r}")
            elif f.type == "float":
                if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                    raise ValueError(f"acquisition setting {f.name}: expected a finite number, got {v!r}")
                object.__setattr__(self, f.name, float(v))
            elif f.name in CHOICES and v not in CHOICES[f.name]:
                raise ValueError(
                    f"acquisition setting {f.name}: expected one of {', '.join(map(repr, CHOICES[f.name]))}, got {v!r}"
                )
        if self.alpha < 0.0:
            raise ValueError(f"acquisition setting alpha: must be >= 0, got {self.alpha!r}")
        for name in ("tau", "learning_rate"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"acquisition setting {name}: must be > 0, got {getattr(self, name)!r}")
        if self.n_restarts > self.n_raw:
            raise ValueError(f"acquisition setting n_restarts ({self.n_restarts}) exceeds n_raw ({self.n_raw})")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


NAMES = tuple(f.name for f in dataclasses.fields(AcquisitionSettings))


def _coerce(name: str, kind: str, value):
    """A number or string from the command line or JSON, as the field's type."""
    if isinstance(value, str) and kind in ("int", "float"):
        text = value.strip()
        try:
            return int(text) if kind == "int" else float(text)
        except ValueError:
            raise ValueError(f"acquisition setting {name}: expected {'an integer' if kind == 'int' else 'a number'}, "
                             f"got {value!r}") from None
    if kind == "float" and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if kind == "int" and isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def acquisition_settings(options: Mapping[str, object] | None = None, base: AcquisitionSettings | None = None
                         ) -> AcquisitionSettings:
    """Settings from a flat ``{name: number | string}`` mapping; unnamed fields keep ``base``'s.

    Numeric strings ("256", "1e-3") are parsed; integral floats are accepted for integer
    fields. Raises ValueError naming the bad key (and listing the valid ones) or value.
    """
    base = AcquisitionSettings() if base is None else base
    options = dict(options or {})
    kinds = {f.name: f.type for f in dataclasses.fields(AcquisitionSettings)}
    for key in options:
        if key not in kinds:
            raise ValueError(f"unknown acquisition setting {key!r}; valid settings: {', '.join(NAMES)}")
    return dataclasses.replace(base, **{k: _coerce(k, kinds[k], v) for k, v in options.items()})
