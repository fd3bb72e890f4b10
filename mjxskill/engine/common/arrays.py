"""The array namespaces the math both engines share is written against: an ``xp`` argument, as
in the array API standard, that is ``JAX`` for the compiled engine's traced values and ``HOST``
for the native engine's numpy values.

``JAX`` is ``jax.numpy`` with ``float_dtype`` float32 (MJX's). ``HOST`` is numpy with
``float_dtype`` float64, but for a few functions evaluated on one value at a time: the native
engine computes one episode's rewards, success test and motion from single values, where the C
library's functions (``math.exp``, ``math.acos``, ``math.atan2``) cost a tenth of numpy's
ufuncs on a 0-d value; on arrays they are numpy's. ``inner`` is the inner product over the last
axis: BLAS's ``dot`` for two vectors on the host, a sum of products under XLA.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np


def _per_value(scalar, ufunc):
    """``scalar`` (math's) when every argument is a single value, else numpy's ``ufunc``."""

    def apply(*args):
        if all(np.ndim(a) == 0 for a in args):
            return scalar(*args)
        return ufunc(*args)

    apply.__name__ = ufunc.__name__
    return apply


def _host_inner(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return np.dot(a, b) if a.ndim == b.ndim == 1 else np.sum(a * b, axis=-1)


def _host_moveaxis(a, source, destination):
    """``np.moveaxis``, with the last axis to the front as a plain transpose: the native engine
    unpacks every quaternion that way, and numpy's axis normalization cost more than the view."""
    a = np.asarray(a)
    if source == -1 and destination == 0:
        return a.transpose((a.ndim - 1, *range(a.ndim - 1)))
    return np.moveaxis(a, source, destination)


class _Namespace:
    """An array module with a few of its functions replaced (the attributes set on it)."""

    def __init__(self, module, **replaced):
        self._module = module
        self.__dict__.update(replaced)

    def __getattr__(self, name):
        return getattr(self._module, name)

    def __repr__(self) -> str:
        return f"<array namespace over {self._module.__name__}>"


JAX = _Namespace(jnp, float_dtype=jnp.float32, inner=lambda a, b: jnp.sum(a * b, axis=-1))
HOST = _Namespace(
    np,
    float_dtype=np.float64,
    inner=_host_inner,
    moveaxis=_host_moveaxis,
    exp=_per_value(math.exp, np.exp),
    arccos=_per_value(math.acos, np.arccos),
    arctan2=_per_value(math.atan2, np.arctan2),
)
