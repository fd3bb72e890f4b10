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
from typing import Any, Mapping, cast

from mjxskill.errors import quote

# Allowed values of the string settings (what each means: the field comments below).
CHOICES = {
    "scalarization": ("chebyshev", "hypervolume"),
    "directions": ("independent", "quasi_random"),
    "single_direction_reference": ("global", "front"),
    "reference": ("warmup", "front"),
    "beyond_reference": ("log", "linear"),
    "prior": ("gamma", "lognormal", "dim_scaled", "small_noise", "unit_outputscale"),
    "pending": ("variance", "values", "draws"),
    "incumbent": ("observed", "posterior_mean"),
    "variance": ("latent", "deflated"),
    "model": ("hybrid", "scalarized", "per_objective"),
    "ei": ("draws", "moments"),
    "draw_pairing": ("shared", "per_direction"),
    "hypervolume_improvement": ("directions", "exact"),
}


@dataclasses.dataclass(frozen=True)
class AcquisitionSettings:
    """Settings of the model-based proposal (hashable: part of the compile cache key).

    One line each: what the setting is and why its default (the measurements behind the
    defaults: benchmarks/RESULTS.md, "Multi-objective BO quality"; what every value does:
    docs/optimizers.md, "The optimizer's settings").
    """

    # Each batch element's scalarization: the hypervolume's (Golovin and Zhang) about a reference point;
    # measured above ParEGO's augmented Chebyshev (RESULTS.md, "Hypervolume scalarizations, per-objective GPs").
    scalarization: str = "hypervolume"
    alpha: float = 0.05  # the augmented Chebyshev coefficient (ParEGO's), used with scalarization "chebyshev"
    # The reference point when none is given: the warm-up's worst plus ref_margin, fixed: the one a run reports against.
    reference: str = "warmup"
    ref_margin: float = 0.1  # that margin, in units of the warm-up's range (BoTorch's infer_reference_point's 0.1)
    # Directions averaged per element: a Monte Carlo estimate of the expected hypervolume improvement.
    n_directions: int = 64
    # A randomized Sobol set of directions per element: the same expectation, less variance than independent ones.
    directions: str = "quasi_random"
    # The batch's last quarter follows one direction each: they refine where one direction points.
    single_direction_share: float = 0.25
    # The improvement estimated by the directions; "exact" (closed form) pays with a given reference only.
    hypervolume_improvement: str = "directions"
    exact_max_points: int = 64  # front points the closed form's grid keeps: bounds its (k + 1)^2 cells per candidate
    # The single-direction elements' reference: the front's nadir, which spreads them over the front's trade-off.
    single_direction_reference: str = "front"
    # Values beyond the reference log-compressed: a heavy tail of bad values does not set the GP's mean and scale.
    beyond_reference: str = "log"
    bucket: int = 64  # training rows padded to a multiple of this: one compile per bucket, not per row count
    n_raw: int = 1024  # random candidates scored per batch element, the Adam restarts' pool
    raw_bounds_share: float = 0.0  # candidates with coordinates on the bounds: pays with three objectives and a given reference only
    n_restarts: int = 10  # best candidates refined by projected Adam (as BoTorch's tutorial)
    n_opt_steps: int = 100  # Adam steps per restart
    learning_rate: float = 0.02  # unit-cube coordinates per Adam step at the start
    final_learning_rate: float = 2e-4  # cosine-decayed to this by the last step: restarts settle on what they found
    fit_starts: int = 2  # L-BFGS starts per GP fit: a second start escapes a poor optimum of the marginal likelihood
    # The GP's hyperparameter prior: the dimension-scaled LogNormal lengthscale prior, not BoTorch's former Gamma priors.
    prior: str = "lognormal"
    fit_steps: int = 50  # L-BFGS steps per start
    # A start stops before fit_steps once its gradient's norm is below this (0: never): the fits are the ask's largest part.
    fit_gradient_tolerance: float = 0.0
    # One fit per batch element up to this many padded rows, one shared fit above: q fits of O(n^3) dominate the ask.
    per_element_fit_max_rows: int = 128
    # Hyperparameters fit on a random subset of at most this many rows (the posterior conditions on all):
    # on every row of a long run the fits dominate the ask (RESULTS.md, "Optimizer overhead").
    fit_max_rows: int = 128
    # A GP per objective with scalarized posterior draws (not one GP per element's scalarization);
    # measured above it (RESULTS.md, "Hypervolume scalarizations, per-objective GPs").
    model: str = "per_objective"
    n_draws: int = 16  # quasi-random posterior draws per point: with 64 directions, 1024 samples of the improvement
    draw_pairing: str = "shared"  # every direction scalarizes the same draws: several draws per direction for one set's cost
    # Earlier points of the batch count at their believed values: a gap one element fills offers nothing to the next.
    pending: str = "values"
    # The incumbent is the posterior mean's best at observed points: re-evaluating a noisy best is no improvement.
    incumbent: str = "posterior_mean"
    # The acquisition sees the posterior variance less the fitted noise: no spurious EI at observed points.
    variance: str = "deflated"
    ei: str = "draws"  # quasi-Monte Carlo log-EI over the draws: the hypervolume scalarization's only estimate
    tau: float = 1e-3  # the softplus width of that log-EI, in scalarized units: a smooth max for Adam
    pibo_beta: float = 2.0  # a parameter prior's weight in the acquisition decays as pibo_beta / n (piBO)
    prior_share: float = 0.5  # the belief: this share of the prior beside the uniform density, which bounds a wrong prior's pull

    def __post_init__(self):
        for f in dataclasses.fields(self):
            problem = _field_problem(f.name, f.type, getattr(self, f.name))
            if problem:
                raise ValueError(f"acquisition setting {f.name}: {problem}")
            if f.type == "float":
                object.__setattr__(self, f.name, float(getattr(self, f.name)))
        if self.scalarization == "hypervolume" and self.ei != "draws":
            raise ValueError(f"acquisition setting ei: {quote(self.ei)} needs scalarization 'chebyshev' (the hypervolume "
                             "scalarization, the default, has only the 'draws' estimate)")
        if self.pending == "draws" and (self.model, self.scalarization, self.ei, self.draw_pairing,
                                        self.hypervolume_improvement) != ("per_objective", "hypervolume", "draws",
                                                                          "shared", "directions"):
            raise ValueError("acquisition setting pending: 'draws' (the earlier elements drawn jointly with the "
                             "candidate) needs model 'per_objective', scalarization 'hypervolume', ei 'draws', "
                             "draw_pairing 'shared' and hypervolume_improvement 'directions'")
        if self.n_restarts > self.n_raw:
            raise ValueError(f"acquisition setting n_restarts ({self.n_restarts}) exceeds n_raw ({self.n_raw})")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


# The defaults of each generation, as changes from AcquisitionSettings() (the newest, GENERATION, changes
# nothing). A run stores the generation it began with (``optimizer_defaults`` in its config.yaml; absent: 1) and
# resumes with it, so a change of the defaults never changes a run in progress. What each generation is:
# 1, ParEGO's log-EI with the hybrid model; 2, the hypervolume scalarization on per-objective GPs; 3 and 4 change
# only what a given reference point with three objectives changes (below). RESULTS.md has how each was chosen.
DEFAULTS_BY_GENERATION: dict[int, dict[str, Any]] = {
    1: {"scalarization": "chebyshev", "n_directions": 1, "directions": "independent", "single_direction_share": 0.0,
        "single_direction_reference": "global", "final_learning_rate": 0.02, "prior": "gamma", "model": "hybrid",
        "n_draws": 128, "pending": "variance", "incumbent": "observed", "variance": "latent"},
    2: {},
    3: {},
    4: {},
}
GENERATION = max(DEFAULTS_BY_GENERATION)

# With a given reference point (MOBOConfig.ref_point) from generation 2 on: 2048 directions, one posterior draw each,
# paired in one Sobol set; about a reference inferred from the warm-up (every robot run) they cost more than they gain.
GIVEN_REFERENCE_DEFAULTS: dict[str, Any] = {"n_directions": 2048, "n_draws": 1, "draw_pairing": "per_direction"}
# With a given reference and three objectives: the closed-form improvement with 4x the candidates and 3x the Adam
# steps (generation 3), and half the candidates on the bounds (generation 4); two objectives lost with both.
_CLOSED_FORM: dict[str, Any] = {"hypervolume_improvement": "exact", "n_raw": 4096, "n_opt_steps": 300}
GIVEN_REFERENCE_THREE_OBJECTIVES_BY_GENERATION: dict[int, dict[str, Any]] = {
    3: _CLOSED_FORM, 4: {**_CLOSED_FORM, "raw_bounds_share": 0.5}}


def acquisition_defaults(generation: int = GENERATION, reference_given: bool = False,
                         n_objectives: int | None = None) -> "AcquisitionSettings":
    """The default settings of ``generation`` (a key of DEFAULTS_BY_GENERATION); with
    ``reference_given``, those of a run whose reference point is known in advance (from
    generation 2 on), which from generation 3 on also depend on ``n_objectives`` (None: not
    known yet, as two). Raises ValueError naming an unknown generation."""
    if generation not in DEFAULTS_BY_GENERATION:
        raise ValueError(f"unknown generation of acquisition defaults {quote(generation)}; known: "
                         f"{', '.join(map(str, DEFAULTS_BY_GENERATION))}")
    changes = DEFAULTS_BY_GENERATION[generation]
    if reference_given and generation >= 2:
        changes = {**changes, **GIVEN_REFERENCE_DEFAULTS}
        if n_objectives == 3:
            changes = {**changes, **GIVEN_REFERENCE_THREE_OBJECTIVES_BY_GENERATION.get(generation, {})}
    return dataclasses.replace(AcquisitionSettings(), **changes)


NAMES = tuple(f.name for f in dataclasses.fields(AcquisitionSettings))
# Each field's type as its name ("int", "float", "str"): this module's annotations are postponed (strings)
_KINDS = {f.name: cast(str, f.type) for f in dataclasses.fields(AcquisitionSettings)}
_NONNEGATIVE = ("alpha", "ref_margin", "pibo_beta", "prior_share", "single_direction_share", "raw_bounds_share",
                "fit_gradient_tolerance")
_AT_MOST_ONE = ("prior_share", "single_direction_share", "raw_bounds_share")
_POSITIVE = ("tau", "learning_rate", "final_learning_rate")
# The largest value of each numeric setting: what a setting sizes (candidates, directions, draws,
# steps, rows) is allocated or run per batch element, so a typo (n_raw=99999999999) exhausted the
# machine in every proposal, and stored with the run it did so on every --resume. Each bound lies
# far beyond the defaults of every generation (n_raw 4096, n_directions 2048, n_draws 128).
MAXIMUM = {"n_raw": 1 << 16, "n_restarts": 1024, "n_opt_steps": 100_000, "n_directions": 1 << 16, "n_draws": 4096,
           "exact_max_points": 256, "bucket": 4096, "fit_starts": 64, "fit_steps": 10_000,
           "per_element_fit_max_rows": 100_000, "fit_max_rows": 100_000,
           "fit_gradient_tolerance": 1.0, "alpha": 1e3, "ref_margin": 1e3, "tau": 1e6, "learning_rate": 10.0, "final_learning_rate": 10.0,
           "pibo_beta": 1e6}


def _field_problem(name: str, kind: str, v) -> str | None:
    """Why ``v`` is no value of the one setting ``name`` (None: it is one); the checks that
    involve several settings are ``AcquisitionSettings.__post_init__``'s."""
    if kind == "int":
        if not isinstance(v, int) or isinstance(v, bool):
            return f"expected an integer, got {quote(v)}"
        if v < 1:
            return f"expected a positive integer, got {quote(v)}"
        if v > MAXIMUM.get(name, v):
            return f"must be at most {MAXIMUM[name]}, got {quote(v)}"
    elif kind == "float":
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            return f"expected a finite number, got {quote(v)}"
        if name in _NONNEGATIVE and v < 0.0:
            return f"must be >= 0, got {quote(v)}"
        if name in _AT_MOST_ONE and v > 1.0:
            return f"must be <= 1 (a fraction), got {quote(v)}"
        if name in _POSITIVE and not v > 0.0:
            return f"must be > 0, got {quote(v)}"
        if v > MAXIMUM.get(name, v):
            return f"must be at most {MAXIMUM[name]:g}, got {quote(v)}"
    elif name in CHOICES and v not in CHOICES[name]:
        return f"expected one of {', '.join(map(repr, CHOICES[name]))}, got {quote(v)}"
    return None


def _coerce(name: str, kind: str, value):
    """A number or string from the command line or JSON, as the field's type."""
    if isinstance(value, str) and kind in ("int", "float"):
        text = value.strip()
        try:
            return int(text) if kind == "int" else float(text)
        except ValueError:
            raise ValueError(f"acquisition setting {name}: expected {'an integer' if kind == 'int' else 'a number'}, "
                             f"got {quote(value)}") from None
    if kind == "float" and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if kind == "int" and isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def setting_value(name: str, value):
    """The checked value of the one setting ``name`` from a number or a string (the text of
    ``--optimizer-option KEY=VALUE`` or a YAML/JSON scalar), as the field's type. Raises
    ValueError naming an unknown key (with the valid ones) or the setting and its bad value.
    What several settings must satisfy together is checked by :func:`acquisition_settings`."""
    if name not in _KINDS:
        raise ValueError(f"unknown acquisition setting {quote(name)}; valid settings: {', '.join(NAMES)}")
    value = _coerce(name, _KINDS[name], value)
    problem = _field_problem(name, _KINDS[name], value)
    if problem:
        raise ValueError(f"acquisition setting {name}: {problem}")
    return float(value) if _KINDS[name] == "float" else value


def acquisition_settings(options: Mapping[str, object] | None = None, base: AcquisitionSettings | None = None
                         ) -> AcquisitionSettings:
    """Settings from a flat ``{name: number | string}`` mapping; unnamed fields keep ``base``'s.

    Numeric strings ("256", "1e-3") are parsed; integral floats are accepted for integer
    fields. Raises ValueError naming the bad key (and listing the valid ones) or value.
    """
    base = AcquisitionSettings() if base is None else base
    values = {key: setting_value(key, value) for key, value in dict(options or {}).items()}
    return dataclasses.replace(base, **values)
