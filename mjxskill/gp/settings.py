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

from mjxskill.errors import quote

# Allowed values of the string settings (what each means: the field comments below).
CHOICES = {
    "scalarization": ("chebyshev", "hypervolume"),
    "directions": ("independent", "quasi_random"),
    "single_direction_reference": ("global", "front"),
    "reference": ("warmup", "front"),
    "beyond_reference": ("log", "linear"),
    "prior": ("gamma", "lognormal"),
    "pending": ("variance", "values"),
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

    The defaults were chosen by measurement against BoTorch's qLogNEHVI and uniform random
    search: benchmarks/RESULTS.md, "Multi-objective BO quality" (the sections named below).
    """

    # The random scalarization of each batch element: "chebyshev" (augmented Chebyshev of
    # objectives normalized by their observed range, flat Dirichlet weights; ParEGO) or
    # "hypervolume" (Golovin and Zhang's hypervolume scalarization about a reference point,
    # uniform directions; hypervolume_scalarization.py). RESULTS.md, "Hypervolume
    # scalarizations, per-objective GPs".
    scalarization: str = "hypervolume"
    alpha: float = 0.05  # augmented Chebyshev coefficient
    # Where the reference point comes from when MOBOConfig.ref_point is None: "warmup" (the
    # worst of the n_init warm-up values plus ref_margin times their range, fixed for the run:
    # the reference mjxskill.train reports the hypervolume against) or "front" (the observed
    # front's nadir plus ref_margin times its extent at each proposal, as BoTorch's
    # infer_reference_point).
    reference: str = "warmup"
    ref_margin: float = 0.1
    # Directions per batch element of the hypervolume scalarization (1: one random
    # scalarization per element; k > 1: their average, a k-direction Monte Carlo estimate of
    # the expected hypervolume improvement; the scalarized model uses the first only). Late in
    # a run the improvement left lies in the gaps between front points, each crossed only by
    # the directions that pass through it. More directions pay off when the reference point is
    # the one the run is judged by (given: GIVEN_REFERENCE_DEFAULTS below), not about one
    # inferred from the warm-up (RESULTS.md, "A given reference point: 2048 directions, a
    # posterior draw each" and "What a run reports").
    n_directions: int = 64
    # How an element's n_directions are drawn: "independent" (uniform, independently) or
    # "quasi_random" (a randomized Sobol set per element: the same expectation, far less
    # variance; hypervolume_scalarization.quasi_random_directions).
    directions: str = "quasi_random"
    # The share of the batch's elements (the last ones) that follow a single random direction
    # each rather than averaging n_directions (only when n_directions > 1): they refine where
    # one direction points, the averaging elements chase the hypervolume.
    single_direction_share: float = 0.25
    # How the other elements of the per-objective model estimate the expected hypervolume
    # improvement: "directions" (the n_directions Monte Carlo estimate above) or "exact" (in
    # closed form over a grid of the non-dominated region, expected_hypervolume.py: no
    # sampling error; two or three objectives, more keep the directions).
    hypervolume_improvement: str = "directions"
    # With three objectives the closed form costs (k + 1)^2 cells per candidate for k points:
    # its grid keeps at most this many of the non-dominated points (the rest, if any, are
    # left out and the improvement near them overestimated; expected_hypervolume.grid).
    exact_max_points: int = 64
    # Their reference point: the run's ("global") or the observed front's nadir plus
    # ref_margin of its extent ("front"; hypervolume_scalarization.front_reference), which
    # spreads their directions over the front's trade-off (RESULTS.md, "Hypervolume
    # scalarizations, per-objective GPs", table "What moved it").
    single_direction_reference: str = "front"
    # Objective values beyond the reference point: "log" compressed (1 + log u in reference
    # units; a heavy tail of bad values no longer sets the GP's mean and scale) or "linear".
    beyond_reference: str = "log"
    bucket: int = 64  # training sets are padded to a multiple of this many rows (one compile per bucket)
    n_raw: int = 1024  # random candidates scored per batch element
    # The share of them with their coordinates on the bounds half the time (proposal._raw_candidates).
    raw_bounds_share: float = 0.0
    n_restarts: int = 10  # best candidates refined by projected Adam
    n_opt_steps: int = 100  # Adam steps per restart
    learning_rate: float = 0.02  # unit-cube coordinates per Adam step
    final_learning_rate: float = 2e-4  # cosine-decayed to this by the last step (equal: constant)
    fit_starts: int = 2  # L-BFGS starts per GP fit (gp.fit)
    # GP hyperparameter prior (gp.log_prior): "gamma" (Matern 5/2 with BoTorch's former Gamma
    # priors) or "lognormal" (the dimension-scaled LogNormal lengthscale prior).
    prior: str = "lognormal"
    fit_steps: int = 50  # L-BFGS steps per start
    # One GP fit per batch element while the padded training set has at most this many
    # rows, one shared fit above (a fit costs O(n^3), q of them dominate the proposal time;
    # per-element fits: RESULTS.md, 'Previous defaults (model = "scalarized")').
    per_element_fit_max_rows: int = 128
    # Hyperparameters are fitted on a random subset of at most this many real rows (the
    # posterior still conditions on all of them): a fit's L-BFGS steps each factorize the
    # n x n covariance, and on every row of a long run they dominate the proposal
    # (RESULTS.md, "Optimizer overhead").
    fit_max_rows: int = 128
    # Which model each batch element uses (see proposal.py): "scalarized" (a GP on the
    # element's scalarization), "per_objective" (a GP per objective, scalarized draws),
    # "hybrid" (the first ceil(q/2) elements scalarized, the rest per-objective).
    model: str = "per_objective"
    # Quasi-random posterior draws per point and direction (per-objective model): with 64
    # directions 16 are 1024 samples of the element's expected improvement.
    n_draws: int = 16
    # How the hypervolume scalarization's directions meet the posterior draws: "shared" (every
    # direction scalarizes the same n_draws draws: n_directions x n_draws samples per point)
    # or "per_direction" (each direction its own n_draws: as many samples, but as many
    # distinct draws as samples; with quasi-random directions the first draw of each comes
    # from the same Sobol set as the direction, one joint quasi-Monte Carlo estimate over
    # directions and posterior draws: hypervolume_scalarization.paired_normal_draws). Shared draws
    # need several per direction (64 x 16) and so leave few directions for the same cost.
    # The Chebyshev scalarization, one weight per element, then uses all those draws.
    draw_pairing: str = "shared"
    # What the points already chosen for the batch change for the later elements of the
    # per-objective model (Kriging believer): "variance" (only the posterior variance shrinks
    # around them) or "values" (also the incumbent counts them at their believed values, so
    # a gap in the front that an earlier element fills offers no improvement again).
    pending: str = "values"
    # The per-objective model's incumbent: the best scalarized "observed" value, or the best
    # of the model's "posterior_mean" at the observed points (where a fitted noise lets the
    # mean pass below an observed optimum, the observed incumbent makes re-evaluating that
    # point look like an improvement).
    incumbent: str = "posterior_mean"
    # The per-objective posterior variance the acquisition sees: "latent" (noise excluded)
    # or "deflated" (minus the fitted noise variance as well: ~0 at observed points of a
    # noiseless objective, where the latent variance stays ~noise and gives a re-evaluation
    # of the incumbent a spurious EI).
    variance: str = "deflated"
    # Per-objective acquisition: "draws" (quasi-MC log-EI) or "moments" (log-EI of the
    # moment-matched Gaussian); tau is the softplus width of "draws", in the units of the
    # scalarized values.
    ei: str = "draws"
    tau: float = 1e-3
    # With a parameter prior (MOBOConfig.prior, gp/prior.py; without one these two change
    # nothing): the optimizer's belief is the prior with weight prior_share beside the uniform
    # density with weight 1 - prior_share. That share of the n_init warm-up points is drawn
    # from the prior, the rest uniformly (0.5 keeps half the warm-up exploring wherever the
    # prior is wrong), and the acquisition is weighted by that mixture to the power
    # pibo_beta / n after n observations (piBO; 0: the prior shapes the warm-up only). The
    # uniform part bounds how far a wrong prior can push the acquisition down: a product
    # prior's log-density falls without bound away from its mean and grows with the
    # dimension, the mixture's never below log(1 - prior_share) (RESULTS.md, "Parameter
    # priors (piBO)").
    # Settings, not Prior fields: they say how the optimizer uses a prior (a search policy,
    # typed and checked like every acquisition setting and set by --optimizer-option), where
    # the Prior says only where the operator believes good values lie. pibo_beta never enters
    # the jitted proposal (beta / n is passed as a traced scalar); its hash only keys the cache.
    pibo_beta: float = 2.0
    prior_share: float = 0.5

    def __post_init__(self):
        for f in dataclasses.fields(self):
            problem = _field_problem(f.name, f.type, getattr(self, f.name))
            if problem:
                raise ValueError(f"acquisition setting {f.name}: {problem}")
            if f.type == "float":
                object.__setattr__(self, f.name, float(getattr(self, f.name)))
        if self.scalarization == "hypervolume" and self.ei != "draws":
            raise ValueError(f"acquisition setting ei: {self.ei!r} needs scalarization 'chebyshev' (the hypervolume "
                             "scalarization, the default, has only the 'draws' estimate)")
        if self.n_restarts > self.n_raw:
            raise ValueError(f"acquisition setting n_restarts ({self.n_restarts}) exceeds n_raw ({self.n_raw})")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


# The defaults of each generation, as changes from AcquisitionSettings() (the newest
# generation, GENERATION, changes nothing). A run stores the generation it began with
# (``optimizer_defaults`` in its config.yaml, mjxskill.runs.run_config; a config.yaml without
# it means 1) and resumes with it, so a later change of the defaults never changes the
# optimizer of a run in progress. Generation 1: log-EI on augmented Chebyshev scalarizations
# (ParEGO) with the hybrid model (RESULTS.md, "Generation 1 defaults"). Generation 3 changes
# only what a given reference point changes, for three objectives (below), and so does 4.
DEFAULTS_BY_GENERATION = {
    1: {"scalarization": "chebyshev", "n_directions": 1, "directions": "independent", "single_direction_share": 0.0,
        "single_direction_reference": "global", "final_learning_rate": 0.02, "prior": "gamma", "model": "hybrid",
        "n_draws": 128, "pending": "variance", "incumbent": "observed", "variance": "latent"},
    2: {},
    3: {},
    4: {},
}
GENERATION = max(DEFAULTS_BY_GENERATION)

# What a given reference point (MOBOConfig.ref_point) changes from generation 2 on (each
# generation's plain defaults above are the same from 2 on). With the reference given, the
# hypervolume the acquisition estimates is the one the run is judged by; about a reference
# inferred from the warm-up (every robot run) these do worse or cost more than they gain, so
# the plain defaults stay there.
# Generation 2: 2048 directions, each with its own posterior draw, paired by one joint Sobol
# set, which resolve the gaps between front points better than 64 x 16 (RESULTS.md, "A given
# reference point: 2048 directions, a posterior draw each").
# Generation 3, three objectives: the expected hypervolume improvement in closed form (the
# single-direction element keeps its direction) and four times the random candidates and three
# times the Adam steps per element: late in a run the improvement left is in narrow gaps, where
# the directions' sampling error and a short search both miss it. With two objectives neither
# pays: the closed form lost on BraninCurrin, the longer search on ZDT1, so generation 2's
# given-reference settings stay there (RESULTS.md, "Three objectives: the expected hypervolume
# improvement in closed form").
GIVEN_REFERENCE_DEFAULTS = {"n_directions": 2048, "n_draws": 1, "draw_pairing": "per_direction"}
# What three objectives change beyond those, by generation.
# Generation 4, three objectives: half the random candidates on the cube's bounds
# (raw_bounds_share). On VehicleSafety the improvement left lies on the cube's faces and
# edges, where no uniform candidate, and so no Adam start, came near it. With two objectives
# it raised both medians, but one BraninCurrin run of ten lost a stretch of the front, so two
# objectives keep generation 2's settings (RESULTS.md, "Candidates on the bounds").
_CLOSED_FORM = {"hypervolume_improvement": "exact", "n_raw": 4096, "n_opt_steps": 300}
GIVEN_REFERENCE_THREE_OBJECTIVES_BY_GENERATION = {3: _CLOSED_FORM, 4: {**_CLOSED_FORM, "raw_bounds_share": 0.5}}


def acquisition_defaults(generation: int = GENERATION, reference_given: bool = False,
                         n_objectives: int | None = None) -> "AcquisitionSettings":
    """The default settings of ``generation`` (a key of DEFAULTS_BY_GENERATION); with
    ``reference_given``, those of a run whose reference point is known in advance (from
    generation 2 on), which from generation 3 on also depend on ``n_objectives`` (None: not
    known yet, as two). Raises ValueError naming an unknown generation."""
    if generation not in DEFAULTS_BY_GENERATION:
        raise ValueError(f"unknown generation of acquisition defaults {generation!r}; known: "
                         f"{', '.join(map(str, DEFAULTS_BY_GENERATION))}")
    changes = DEFAULTS_BY_GENERATION[generation]
    if reference_given and generation >= 2:
        changes = {**changes, **GIVEN_REFERENCE_DEFAULTS}
        if n_objectives == 3:
            changes = {**changes, **GIVEN_REFERENCE_THREE_OBJECTIVES_BY_GENERATION.get(generation, {})}
    return dataclasses.replace(AcquisitionSettings(), **changes)


NAMES = tuple(f.name for f in dataclasses.fields(AcquisitionSettings))
_KINDS = {f.name: f.type for f in dataclasses.fields(AcquisitionSettings)}
_NONNEGATIVE = ("alpha", "ref_margin", "pibo_beta", "prior_share", "single_direction_share", "raw_bounds_share")
_AT_MOST_ONE = ("prior_share", "single_direction_share", "raw_bounds_share")
_POSITIVE = ("tau", "learning_rate", "final_learning_rate")
# The largest value of each numeric setting: what a setting sizes (candidates, directions, draws,
# steps, rows) is allocated or run per batch element, so a typo (n_raw=99999999999) exhausted the
# machine in every proposal, and stored with the run it did so on every --resume. Each bound lies
# far beyond the defaults of every generation (n_raw 4096, n_directions 2048, n_draws 128).
MAXIMUM = {"n_raw": 1 << 16, "n_restarts": 1024, "n_opt_steps": 100_000, "n_directions": 1 << 16, "n_draws": 4096,
           "exact_max_points": 256, "bucket": 4096, "fit_starts": 64, "fit_steps": 10_000,
           "per_element_fit_max_rows": 100_000, "fit_max_rows": 100_000,
           "alpha": 1e3, "ref_margin": 1e3, "tau": 1e6, "learning_rate": 10.0, "final_learning_rate": 10.0,
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
            return f"must be >= 0, got {v!r}"
        if name in _AT_MOST_ONE and v > 1.0:
            return f"must be <= 1 (a fraction), got {v!r}"
        if name in _POSITIVE and not v > 0.0:
            return f"must be > 0, got {v!r}"
        if v > MAXIMUM.get(name, v):
            return f"must be at most {MAXIMUM[name]:g}, got {v!r}"
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
