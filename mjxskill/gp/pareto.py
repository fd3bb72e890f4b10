"""Pareto dominance and exact hypervolume for minimization problems (numpy, host side)."""

from __future__ import annotations

import numpy as np

from mjxskill.errors import quote


def _as_points(y, where: str) -> np.ndarray:
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 2:
        raise ValueError(f"{where}: expected an (n, m) array of objective values, got shape {y.shape}")
    return y


def pareto_mask(y, deduplicate: bool = True) -> np.ndarray:
    """Which rows of y are non-dominated (minimization).

    A row is dominated when another row is <= in every objective and < in at least one.
    Rows with a NaN or infinite value are never on the front and dominate nothing.
    Identical rows do not dominate each other: with ``deduplicate`` only the first of them is
    marked, otherwise all are.

    Args:
      y: (n, m) objective values.
    Returns:
      (n,) bool mask.
    """
    y = _as_points(y, "pareto_mask")
    n = y.shape[0]
    finite = np.all(np.isfinite(y), axis=1)
    mask = finite.copy()
    idx = np.flatnonzero(finite)
    p = y[idx]
    # Chunked O(n^2 m) comparison: fine for the few thousand points of a training run.
    for start in range(0, len(p), 512):
        block = p[start : start + 512]
        le = np.all(p[None, :, :] <= block[:, None, :], axis=2)  # (b, k): k <= row
        lt = np.any(p[None, :, :] < block[:, None, :], axis=2)
        dominated = np.any(le & lt, axis=1)
        mask[idx[start : start + len(block)]] = ~dominated
    if deduplicate and n:
        _, first = np.unique(y[mask], axis=0, return_index=True)
        kept = np.flatnonzero(mask)[np.sort(first)]
        mask[:] = False
        mask[kept] = True
    return mask


def _hv_sorted_recursive(p: np.ndarray, ref: np.ndarray) -> float:
    """Hypervolume of points p (k, m), all strictly better than ref, by slicing the last axis."""
    k, m = p.shape
    if k == 0:
        return 0.0
    if m == 1:
        return float(ref[0] - p[:, 0].min())
    if m == 2:
        order = np.lexsort((p[:, 1], p[:, 0]))
        xs, ys = p[order, 0], np.minimum.accumulate(p[order, 1])
        widths = np.diff(np.append(xs, ref[0]))
        return float(np.sum(widths * (ref[1] - ys)))
    order = np.argsort(p[:, -1], kind="stable")
    p = p[order]
    levels = np.append(p[:, -1], ref[-1])
    total = 0.0
    for i in range(k):
        depth = levels[i + 1] - levels[i]
        if depth > 0:
            slab = p[: i + 1, :-1]
            slab = slab[pareto_mask(slab)]
            total += depth * _hv_sorted_recursive(slab, ref[:-1])
    return total


def hypervolume(y, ref) -> float:
    """Exact hypervolume dominated by y and bounded by the reference point (minimization).

    Rows that are not strictly better than ref in every objective, or hold NaN/inf, add
    nothing. Exact for any m (slicing recursion; cost grows as n^(m-1), fine for m <= 4
    and a few hundred points).

    Args:
      y: (n, m) objective values; ref: (m,) reference point.
    """
    y = _as_points(y, "hypervolume")
    ref = np.asarray(ref, dtype=np.float64)
    if ref.shape != (y.shape[1],) or not np.all(np.isfinite(ref)):
        raise ValueError(f"hypervolume: reference point {quote(ref)} must be {y.shape[1]} finite numbers")
    ok = np.all(np.isfinite(y), axis=1) & np.all(y < ref, axis=1)
    p = y[ok]
    p = p[pareto_mask(p)]
    return _hv_sorted_recursive(p, ref)
