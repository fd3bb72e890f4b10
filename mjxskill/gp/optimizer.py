"""Ask/tell multi-objective Bayesian optimizer (optax-style ``init``/``ask``/``tell``).

``state = init(config)``; ``X = ask(state)`` returns the next batch (uniform random warm-up
until ``n_init`` points are observed, then model-based); ``state = tell(state, X, Y)``
records results; ``save_state``/``load_state`` write and read NPZ with the config as JSON
(no pickle). Objectives are minimized.

Determinism: the randomness of a proposal derives from ``(seed, number of observations)``
only, so a run restored from disk proposes exactly what the uninterrupted run would.

Static shapes: the model sees the training set padded to the next multiple of
``config.acquisition.bucket`` rows, so the proposal compiles once per bucket, not once per batch.

A parameter prior (``MOBOConfig.prior``, gp/prior.py) shapes the warm-up (a fraction of its
points drawn from the prior) and weights the acquisition (piBO); without one, the prior's
settings (``prior_share``, ``pibo_beta``) change no proposal.

Non-finite objective values (a crashed rollout) are kept in the state and on disk; the
model sees them as the worst value observed for that objective (1 after normalization),
which steers proposals away from them without breaking the GP.

Known observation noise: a row may be the mean of several noisy evaluations (a parameter set
rolled out in several randomized worlds), with a known noise variance of each objective's
value (``MOBOState.noise``; ``tell(..., noise=...)``, or ``observed`` for a state built from
pooled rows). The per-objective GPs then fit each row with its own noise beside their fitted
noise (``proposal.propose_batch``'s ``obs_noise``). A state has noise for all its rows or for
none (None: no known noise).

Precision: the GP runs in float64 under a local ``jax.enable_x64(True)`` scope; importing or
using this module does not change ``jax_enable_x64`` for the rest of the process.
"""

from __future__ import annotations

import dataclasses
import io
import json
from pathlib import Path
from typing import Any, Callable, Mapping, NamedTuple

import jax
import numpy as np

from mjxskill._files import read_regular
from mjxskill.errors import quote
from mjxskill.gp.config import STATE_FORMAT, MOBOConfig, config_from_json
from mjxskill.gp.hypervolume_scalarization import reference_point, warmup_reference
from mjxskill.gp.pareto import pareto_mask
from mjxskill.gp.prior import Prior, pibo_weight, prior_rows, sample_unit, unit_prior
from mjxskill.gp.proposal import propose_batch
from mjxskill.gp.settings import CHOICES, AcquisitionSettings, acquisition_defaults, acquisition_settings


class MOBOState(NamedTuple):
    """Everything a run needs to continue; observations live on the host."""

    config: MOBOConfig
    x: np.ndarray  # (n, d) float64, in the config's bounds
    y: np.ndarray  # (n, m) float64, may hold NaN/inf (kept, penalized in the model)
    # (n, m) float64 noise variances of the rows' objective values (objective units squared),
    # or None: no known noise.
    noise: np.ndarray | None = None


class MOBOResult(NamedTuple):
    x: np.ndarray  # (n, d) all evaluated points
    y: np.ndarray  # (n, m) their objective values
    pareto_x: np.ndarray  # (p, d) non-dominated points
    pareto_y: np.ndarray  # (p, m)
    state: MOBOState

    # Upper-case aliases (res.X, res.pareto_Y), the names of the usual MOBO notation.
    @property
    def X(self):
        return self.x

    @property
    def Y(self):
        return self.y

    @property
    def pareto_X(self):
        return self.pareto_x

    @property
    def pareto_Y(self):
        return self.pareto_y


def init(config: MOBOConfig) -> MOBOState:
    """The state of a run that has observed nothing yet."""
    return MOBOState(
        config,
        np.zeros((0, config.dim), np.float64),
        np.zeros((0, config.n_objectives), np.float64),
    )


def _normalization(y: np.ndarray):
    """Per-objective (lo (m,), span (m,)) of the finite values: y_norm = (y - lo) / span."""
    finite = np.isfinite(y)
    lo, span = np.zeros(y.shape[1]), np.ones(y.shape[1])
    for i in range(y.shape[1]):
        col = y[finite[:, i], i]
        if col.size:
            lo[i] = col.min()
            span[i] = col.max() - lo[i] if col.max() > lo[i] else 1.0
    return lo, span


def _normalized_objectives(y: np.ndarray) -> np.ndarray:
    """(n, m) objectives scaled to [0, 1] by the observed finite min/max; non-finite -> 1."""
    lo, span = _normalization(y)
    return np.where(np.isfinite(y), (y - lo) / span, 1.0)


def reference_of(state: MOBOState) -> np.ndarray:
    """(m,) the hypervolume scalarizations' reference point, in objective units: the config's,
    or inferred as ``acquisition.reference`` says (from the warm-up rows or the current front)."""
    cfg = state.config
    assert cfg.acquisition is not None  # MOBOConfig.__post_init__ sets it
    if cfg.ref_point is not None:
        return np.asarray(cfg.ref_point, np.float64)
    if cfg.acquisition.reference == "warmup":
        return warmup_reference(state.y[: cfg.n_init], cfg.acquisition.ref_margin)
    return reference_point(state.y, cfg.acquisition.ref_margin)


def _padded_training_set(state: MOBOState):
    """(x, y_norm, mask, ref) padded to the bucket size, in the proposal's units."""
    cfg = state.config
    assert cfg.acquisition is not None  # MOBOConfig.__post_init__ sets it
    lo, hi = np.asarray(cfg.bounds)
    n = len(state.x)
    size = cfg.acquisition.bucket * -(-n // cfg.acquisition.bucket)
    x = np.full((size, cfg.dim), 0.5)
    y = np.zeros((size, cfg.n_objectives))
    mask = np.zeros((size,), bool)
    x[:n] = (state.x - lo) / (hi - lo)
    y[:n] = _normalized_objectives(state.y)
    mask[:n] = True
    y_lo, y_span = _normalization(state.y)
    ref = (reference_of(state) - y_lo) / y_span
    # No finite value to place it by: just beyond the worst observed (normalized 1).
    ref = np.where(np.isfinite(ref), ref, 1.0 + cfg.acquisition.ref_margin)
    return x, y, mask, ref


def _noise_arguments(state: MOBOState, size: int) -> dict:
    """propose_batch's obs_noise (size, m), padded like the training set, and new_noise (m,),
    the median noise of the rows with a finite value, in normalized units (noise / span^2);
    no arguments for a state without noise. A non-finite value is replaced by the worst one:
    its noise is 0."""
    if state.noise is None:
        return {}
    _, span = _normalization(state.y)
    finite = np.isfinite(state.y)
    noise = np.where(finite, state.noise, 0.0) / span**2
    obs = np.zeros((size, noise.shape[1]))
    obs[: len(noise)] = noise
    new = np.array([np.median(noise[finite[:, i], i]) if finite[:, i].any() else 0.0 for i in range(noise.shape[1])])
    return {"obs_noise": obs, "new_noise": new}


def proposal_key(seed: int, n_observations: int):
    """The PRNG key of the proposal made after n_observations (a raw uint32 key)."""
    return jax.random.fold_in(jax.random.PRNGKey(seed), n_observations)


def ask(state: MOBOState, num: int | None = None) -> np.ndarray:
    """The next batch to evaluate, (q, d) float64 inside the bounds.

    q is ``num`` or ``config.batch_size``, except during warm-up, where it is cut so that
    exactly ``n_init`` random points are drawn before the model takes over. Pure: asking
    twice without telling returns the same batch.

    With a prior, the warm-up points that ``prior_rows`` picks (a fraction
    ``acquisition.prior_share``) are drawn from it and the rest stay the uniform
    draws a run without a prior makes; the model's proposals maximize log-EI plus
    (pibo_beta / n) log belief(x) after n observations, the belief the prior mixed
    with the uniform density (``proposal.prior_weighted``).
    """
    cfg = state.config
    assert cfg.acquisition is not None  # MOBOConfig.__post_init__ sets it
    q = cfg.batch_size if num is None else int(num)
    if q < 1:
        raise ValueError(f"ask: batch size must be positive, got {quote(num)}")
    lo, hi = np.asarray(cfg.bounds)
    n = len(state.x)
    if n < cfg.n_init:
        q = min(q, cfg.n_init - n)
        u = np.random.default_rng([cfg.seed, n]).random((q, cfg.dim))
        if cfg.prior is not None:
            rows = prior_rows(n, q, cfg.acquisition.prior_share)
            drawn = sample_unit(unit_prior(cfg.prior, cfg.bounds), np.random.default_rng([cfg.seed, n, _PRIOR_STREAM]), q)
            u = np.where(rows[:, None], drawn, u)
        return lo + u * (hi - lo)
    x, y, mask, ref = _padded_training_set(state)
    with jax.enable_x64(True):
        prior_args: tuple = ()
        if cfg.prior is not None:
            prior_args = (jax.tree.map(jax.numpy.asarray, unit_prior(cfg.prior, cfg.bounds)),
                          jax.numpy.asarray(pibo_weight(cfg.acquisition.pibo_beta, n), jax.numpy.float64))
        points, _ = propose_batch(x, y, mask, proposal_key(cfg.seed, n), ref, *prior_args, q=q,
                                  settings=cfg.acquisition, **_noise_arguments(state, len(x)))
        u = np.asarray(points, np.float64)
    return np.clip(lo + u * (hi - lo), lo, hi)


def tell(state: MOBOState, x, y, noise=None) -> MOBOState:
    """A new state with the evaluated batch appended. x (q, d) inside bounds, y (q, m);
    noise (q, m) the noise variances of y (finite and >= 0 where y is finite), or None.

    A state holds noise for all its rows or for none: noise must be given exactly when the
    state's rows have it (any way for a state without rows).
    """
    cfg = state.config
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != cfg.dim:
        raise ValueError(f"tell: x must have shape (q, {cfg.dim}), got {x.shape}")
    if y.shape != (x.shape[0], cfg.n_objectives):
        raise ValueError(
            f"tell: y must have shape ({x.shape[0]}, {cfg.n_objectives}) to match x, got {y.shape}"
        )
    if not np.all(np.isfinite(x)):
        row = int(np.flatnonzero(~np.all(np.isfinite(x), axis=1))[0])
        raise ValueError(f"tell: x row {row} is not finite: {x[row].tolist()}")
    lo, hi = np.asarray(cfg.bounds)
    tol = 1e-9 * (hi - lo)
    outside = np.any((x < lo - tol) | (x > hi + tol), axis=1)
    if outside.any():
        row = int(np.flatnonzero(outside)[0])
        raise ValueError(f"tell: x row {row} = {x[row].tolist()} lies outside the bounds {cfg.bounds}")
    if len(state.x) and (noise is None) != (state.noise is None):
        have = "no noise" if state.noise is None else "noise"
        raise ValueError(f"tell: the state's {len(state.x)} rows have {have}; noise must be given for all rows or "
                         f"for none, got noise={'None' if noise is None else 'an array'}")
    if noise is None:
        return state._replace(x=np.concatenate([state.x, x]), y=np.concatenate([state.y, y]), noise=None)
    noise = np.asarray(noise, dtype=np.float64)
    if noise.shape != y.shape:
        raise ValueError(f"tell: noise must have shape {y.shape} to match y, got {noise.shape}")
    bad = np.isfinite(y) & ~(np.isfinite(noise) & (noise >= 0))
    if bad.any():
        row = int(np.flatnonzero(bad.any(axis=1))[0])
        raise ValueError(f"tell: noise row {row} = {noise[row].tolist()} is not a variance (finite, >= 0)")
    earlier = state.noise if state.noise is not None else np.zeros((0, cfg.n_objectives))
    return state._replace(x=np.concatenate([state.x, x]), y=np.concatenate([state.y, y]),
                          noise=np.concatenate([earlier, noise]))


def observed(config: MOBOConfig, x, y, noise=None) -> MOBOState:
    """The state of a run that observed x (n, d), y (n, m) and, if given, their noise
    variances noise (n, m): e.g. rebuilt from pooled rows before each ask."""
    return tell(init(config), x, y, noise)


def save_state(state: MOBOState, path) -> None:
    """Writes the state as NPZ (arrays, the noise array when the state has one, and the config
    as JSON); no pickle. ``path``: a file name, or a binary file open for writing."""
    config_json = json.dumps({"format": STATE_FORMAT, "config": state.config.to_dict()})
    noise: dict[str, Any] = {} if state.noise is None else {"noise": state.noise}  # Any: savez's stubs
    if hasattr(path, "write"):
        np.savez(path, x=state.x, y=state.y, config_json=np.array(config_json), **noise)
        return
    with open(path, "wb") as fh:
        np.savez(fh, x=state.x, y=state.y, config_json=np.array(config_json), **noise)


_PRIOR_STREAM = 0x9A10  # the prior's warm-up draws: a generator apart from the uniform ones

def load_state(path) -> MOBOState:
    """Reads a state written by :func:`save_state` (or by format 1), validating it; a file
    without a noise array is a state without noise."""
    path = Path(path)
    # a regular file only (a FIFO in its place would block np.load forever), then parsed from memory
    with np.load(io.BytesIO(read_regular(path)), allow_pickle=False) as data:
        missing = {"x", "y", "config_json"} - set(data.files)
        if missing:
            raise ValueError(f"load_state: {path} lacks {sorted(missing)}")
        meta = json.loads(str(data["config_json"]))
        x, y = data["x"].astype(np.float64), data["y"].astype(np.float64)
        noise = data["noise"].astype(np.float64) if "noise" in data.files else None
    state = init(config_from_json(meta, path))
    if x.shape[0] == 0:
        return state
    try:
        return tell(state, x, y, noise)
    except ValueError as err:
        raise ValueError(f"load_state: {path}: {err}") from None


def minimize(
    f: Callable[[np.ndarray], np.ndarray],
    bounds,
    budget: int,
    batch_size: int = 8,
    n_init: int = 40,
    seed: int = 0,
    callback: Callable[[MOBOState], None] | None = None,
    acquisition: AcquisitionSettings | Mapping | None = None,
    ref_point=None,
    prior: Prior | Mapping | None = None,
    **options,
) -> MOBOResult:
    """Minimizes the vector objective f over a box with ``budget`` evaluations.

    Args:
      f: maps (q, d) points to (q, m) objective values; called once per batch.
      bounds: (2, d) lower and upper bounds.
      budget: total number of evaluations (the last batch is cut to fit).
      acquisition: the acquisition settings, or a mapping of some over the defaults (default:
        the defaults; with ``ref_point`` those of a given reference point, MOBOConfig's rule).
      ref_point: (m,) reference point of the hypervolume scalarizations (MOBOConfig.ref_point).
      prior: where good values are believed to lie (``Prior``; MOBOConfig.prior).
      options: acquisition settings by name, applied over ``acquisition`` (as
        :func:`acquisition_settings` reads them, e.g. ``n_raw=256``).
    """
    if budget < n_init:
        raise ValueError(f"minimize: budget ({budget}) is smaller than n_init ({n_init})")
    if isinstance(prior, str):
        # "prior" is also the acquisition setting of the GP's hyperparameter prior ("gamma",
        # "lognormal"); as a keyword of minimize it is the parameter prior.
        hint = (f"; for the GP's hyperparameter prior pass acquisition={{'prior': {prior!r}}}" if prior in CHOICES["prior"]
                else "")
        raise ValueError(f"minimize: prior={quote(prior)} is not a parameter prior (a Prior or {{'mean': ..., 'std': ...}}){hint}")

    def evaluate(x):
        y = np.asarray(f(x), dtype=np.float64)
        if y.ndim != 2 or y.shape[0] != x.shape[0]:
            raise ValueError(f"minimize: f returned shape {y.shape} for {x.shape[0]} points; expected (q, m)")
        return y

    def resolved(n_objectives):
        # The defaults with a given reference point depend on the number of objectives.
        defaults = acquisition_defaults(reference_given=ref_point is not None, n_objectives=n_objectives)
        base = acquisition_settings(acquisition, base=defaults) if acquisition is None or isinstance(
            acquisition, Mapping) else acquisition
        return acquisition_settings(options, base=base)

    # The number of objectives is learned from the first warm-up batch (the warm-up draws
    # use none of the acquisition settings but prior_share, the same whatever that number).
    probe = MOBOConfig(bounds=bounds, n_objectives=1, batch_size=batch_size, n_init=n_init, seed=seed,
                       acquisition=resolved(None), prior=prior)  # type: ignore[arg-type]  # MOBOConfig reads a mapping too
    x0 = ask(init(probe))
    y0 = evaluate(x0)
    cfg = dataclasses.replace(probe, n_objectives=y0.shape[1], ref_point=ref_point, acquisition=resolved(y0.shape[1]))
    state = tell(init(cfg), x0, y0)
    if callback:
        callback(state)
    while len(state.x) < budget:
        x = ask(state, num=min(batch_size, budget - len(state.x)))
        state = tell(state, x, evaluate(x))
        if callback:
            callback(state)
    front = pareto_mask(state.y)
    return MOBOResult(state.x, state.y, state.x[front], state.y[front], state)
