"""A prior over where good parameter values lie, and what the optimizer does with it.

``Prior(mean, std, weights=None)``: a mixture of K components, each a product over the d
dimensions of Gaussians (mean, standard deviation in the parameter's units) truncated to the
bounds. ``mean`` and ``std`` are (d,) for one component or (K, d); ``weights`` (K,) positive
and summing to 1 (default: equal); ``std`` may be one number for all. An operator's belief is
one component; a prior built from an earlier run's Pareto front is one component per Pareto
solution.

The optimizer uses it twice (Hvarfner et al. 2022, piBO):

* the warm-up draws a fraction of its points from the prior, the rest uniformly
  (``AcquisitionSettings.prior_share``, see ``prior_rows``);
* the acquisition is weighted by the belief (the prior with weight ``prior_share`` beside the
  uniform density) with an influence that decays with the number of observations n:
  acq(x) * belief(x)^(beta / n). Our acquisition is log-EI, so the proposal maximizes
  ``log_acq(x) + (beta / n) * log belief(x)`` (``AcquisitionSettings.pibo_beta``;
  ``proposal.prior_weighted``).
  Early on the prior steers the search; as data accumulate the model's EI dominates, so a
  misleading prior costs evaluations but not the final front (measured: benchmarks/RESULTS.md,
  "Parameter priors (piBO)").

The proposal sees the prior in unit-cube coordinates (``UnitPrior``, arrays traced by the
jitted proposal: a changed prior with the same number of components does not retrace). Its
log-density there differs from the one in parameter units by the constant sum(log(hi - lo)),
which changes no argmax. Its log-density under jax, the term the proposal adds, is
``mjxskill.gp.prior_density``: this module is numpy only, so a run's configuration is checked
(``runs.run_config``) without importing jax.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Mapping, NamedTuple

import numpy as np
from scipy.special import ndtr, ndtri

from mjxskill.errors import quote

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)
_WEIGHT_TOLERANCE = 1e-6  # how far the weights' sum may be from 1 (they are renormalized exactly)


def _matrix(name: str, value) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"Prior.{name}: expected numbers, got {quote(value)}") from None
    if a.ndim == 1:
        a = a[None]
    if a.ndim != 2 or a.shape[1] < 1 or a.shape[0] < 1:
        raise ValueError(f"Prior.{name}: expected shape (d,) or (K, d), got {np.shape(value)}")
    return a


@dataclasses.dataclass(frozen=True)
class Prior:
    """A mixture of truncated Gaussians over the parameter box (immutable, JSON-able).

    Stored as nested tuples: ``mean`` and ``std`` (K, d), ``weights`` (K,). The bounds are the
    optimizer's (``check_bounds``): a prior is checked against them when a ``MOBOConfig`` holds it.
    """

    mean: tuple
    std: tuple
    weights: tuple | None = None

    def __post_init__(self):
        mean = _matrix("mean", self.mean)
        std = _matrix("std", np.full(mean.shape, self.std) if np.ndim(self.std) == 0 else self.std)
        if std.shape[0] == 1 and mean.shape[0] > 1:
            std = np.broadcast_to(std, mean.shape)
        if std.shape != mean.shape:
            raise ValueError(f"Prior.std: shape {std.shape} does not match the mean's {mean.shape}")
        for k, i in zip(*np.nonzero(~np.isfinite(mean))):
            raise ValueError(f"Prior.mean: component {k}, dimension {i} is not finite: {float(mean[k, i])!r}")
        for k, i in zip(*np.nonzero(~(np.isfinite(std) & (std > 0)))):
            raise ValueError(f"Prior.std: component {k}, dimension {i} must be > 0 and finite, got {float(std[k, i])!r}")
        K = mean.shape[0]
        if self.weights is None:
            w = np.full(K, 1.0 / K)
        else:
            w = np.asarray(self.weights, dtype=np.float64).reshape(-1)
            if w.shape != (K,):
                raise ValueError(f"Prior.weights: expected {K} weights, one per component, got {w.shape[0]}")
            for k in np.flatnonzero(~(np.isfinite(w) & (w > 0))):
                raise ValueError(f"Prior.weights: weight {k} must be > 0 and finite, got {float(w[k])!r}")
            if abs(w.sum() - 1.0) > _WEIGHT_TOLERANCE:
                raise ValueError(f"Prior.weights: must sum to 1, got {float(w.sum())!r} ({w.tolist()})")
            w = w / w.sum()
        object.__setattr__(self, "mean", tuple(tuple(float(v) for v in row) for row in mean))
        object.__setattr__(self, "std", tuple(tuple(float(v) for v in row) for row in std))
        object.__setattr__(self, "weights", tuple(float(v) for v in w))

    @property
    def dim(self) -> int:
        return len(self.mean[0])

    @property
    def n_components(self) -> int:
        return len(self.mean)

    def check_bounds(self, bounds) -> None:
        """ValueError unless the prior fits the (2, d) ``bounds``: d dimensions, every mean inside."""
        lo, hi = np.asarray(bounds, dtype=np.float64)
        if self.dim != lo.shape[0]:
            raise ValueError(f"Prior: {self.dim} dimensions, the bounds have {lo.shape[0]}")
        mean = np.asarray(self.mean)
        for k, i in zip(*np.nonzero((mean < lo) | (mean > hi))):
            raise ValueError(f"Prior.mean: component {k}, dimension {i} = {mean[k, i]:g} lies outside the bounds "
                             f"[{lo[i]:g}, {hi[i]:g}]")

    def to_dict(self) -> dict:
        assert self.weights is not None  # __post_init__ sets it
        return {"mean": [list(r) for r in self.mean], "std": [list(r) for r in self.std], "weights": list(self.weights)}

    @classmethod
    def from_dict(cls, data: Mapping) -> "Prior":
        """The prior of a ``to_dict`` mapping (JSON, config.yaml); ValueError names a bad key."""
        if not isinstance(data, Mapping):
            raise ValueError(f"Prior: expected a mapping with mean, std and weights, got {quote(data)}")
        unknown = set(data) - {"mean", "std", "weights"}
        if unknown or not {"mean", "std"} <= set(data):
            raise ValueError(f"Prior: expected the keys mean, std (and weights), got {sorted(data)}")
        return cls(mean=data["mean"], std=data["std"], weights=data.get("weights"))


def prior_of(value) -> Prior | None:
    """A ``Prior`` from a Prior, a ``to_dict`` mapping or None."""
    if value is None or isinstance(value, Prior):
        return value
    if isinstance(value, Mapping):
        return Prior.from_dict(value)
    raise ValueError(f"prior: expected a Prior or a mapping, got {quote(value)}")


class UnitPrior(NamedTuple):
    """The prior in unit-cube coordinates, as the jitted proposal takes it (traced arrays).

    mean, std: (K, d). log_weights: (K,). log_const: (K,) log w_k - sum_i (log std_ki + log Z_ki +
    log sqrt(2 pi)), Z_ki the mass of component k's Gaussian in [0, 1] along dimension i.
    """

    mean: np.ndarray
    std: np.ndarray
    log_weights: np.ndarray
    log_const: np.ndarray


def _log_mass(mean: np.ndarray, std: np.ndarray, lo, hi) -> np.ndarray:
    """log(Phi(b) - Phi(a)), a = (lo - mean) / std, b = (hi - mean) / std, with lo <= mean <= hi
    (a <= 0 <= b): written as log(1 - Phi(a) - Phi(-b)), no cancellation of two values near 1."""
    a, b = (lo - mean) / std, (hi - mean) / std
    return np.log1p(-(ndtr(a) + ndtr(-b)))


def unit_prior(prior: Prior, bounds) -> UnitPrior:
    """The prior in the unit cube of the (2, d) ``bounds``, as the jitted proposal takes it."""
    lo, hi = np.asarray(bounds, dtype=np.float64)
    mean = (np.asarray(prior.mean) - lo) / (hi - lo)
    std = np.asarray(prior.std) / (hi - lo)
    log_z = _log_mass(mean, std, 0.0, 1.0)
    log_weights = np.log(np.asarray(prior.weights))
    return UnitPrior(mean, std, log_weights, log_weights - np.sum(np.log(std) + log_z + _LOG_SQRT_2PI, axis=1))


def pibo_weight(beta: float, n_observations: int) -> float:
    """piBO's exponent of the prior after n observations: beta / n (the log-acquisition shift
    is this times log belief(x))."""
    return float(beta) / max(int(n_observations), 1)


def sample_unit(prior: UnitPrior, rng: np.random.Generator, num: int) -> np.ndarray:
    """(num, d) draws from the prior in [0, 1]^d: a component by its weight, then each
    dimension by the inverse CDF of its truncated Gaussian."""
    K, d = prior.mean.shape
    w = np.exp(prior.log_weights - prior.log_weights.max())
    k = rng.choice(K, size=num, p=w / w.sum())
    mean, std = prior.mean[k], prior.std[k]
    # The mean lies in [0, 1], so a <= 0 <= b: neither CDF value is lost to rounding near 1
    # unless its tail mass is below float64's resolution anyway.
    a, b = -mean / std, (1.0 - mean) / std
    r = rng.random((num, d))
    p_lo, p_hi = ndtr(a), ndtr(b)
    z = ndtri(p_lo + r * (p_hi - p_lo))
    return np.clip(mean + std * z, 0.0, 1.0)


def prior_rows(start: int, num: int, fraction: float) -> np.ndarray:
    """(num,) bool: which of the warm-up points start..start+num-1 come from the prior. Point i
    does when ceil((i + 1) f) > ceil(i f): the prior's points are spread evenly over the
    warm-up, ceil(f n_init) of them, and a point's source depends on its index alone."""
    i = np.arange(start, start + num)
    return np.ceil((i + 1) * fraction - 1e-12) > np.ceil(i * fraction - 1e-12)


__all__ = ["Prior", "UnitPrior", "pibo_weight", "prior_of", "prior_rows",
           "sample_unit", "unit_prior"]
