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

try:  # the ufunc ``np.clip`` calls (numpy 2; numpy 1 names its package ``core``)
    from numpy._core.umath import clip as _CLIP  # type: ignore[attr-defined]  # numpy's stubs omit the ufunc
except ImportError:  # pragma: no cover
    from numpy.core.umath import clip as _CLIP  # type: ignore[no-redef]  # the same ufunc under numpy 1


def _per_value(scalar, ufunc):
    """``scalar`` (math's) when every argument is a single value, else numpy's ``ufunc``."""

    def apply(*args):
        for a in args:  # a Python float is a single value without asking numpy
            if type(a) is not float and np.ndim(a) != 0:
                return ufunc(*args)
        return scalar(*args)

    apply.__name__ = ufunc.__name__
    return apply


def _host_inner(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return np.dot(a, b) if a.ndim == b.ndim == 1 else np.sum(a * b, axis=-1)


def _host_norm(x, ord=None, axis=None, keepdims=False):
    """``np.linalg.norm``; for a float64 array and the 2-norm over all of it or one axis, what it
    runs for one, without its argument handling (~3 us a call, and the native engine asks for
    ~10 per episode and tick): the same operations, so the same values."""
    if ord is None and type(x) is np.ndarray and x.dtype == np.float64:
        if axis is None and not keepdims:
            x = x.ravel(order="K")
            return np.sqrt(x.dot(x))
        if type(axis) is int:
            s = (x.conj() * x).real
            return np.sqrt(np.add.reduce(s, axis=(axis,), keepdims=keepdims))
    return np.linalg.norm(x, ord, axis, keepdims)


def _host_clip(a, a_min, a_max):
    """``np.clip``: for a float64 array or value and both bounds, the ufunc it ends in, called
    without its wrappers (the same function, so the same values)."""
    if a_min is not None and a_max is not None and (type(a) is np.float64 or (type(a) is np.ndarray and a.dtype == np.float64)):
        return _CLIP(a, a_min, a_max)
    return np.clip(a, a_min, a_max)


def _host_stack(arrays, axis=0):
    """``np.stack``: float64 values or arrays of one shape along a new last axis copied into
    place (what ``np.stack`` does through ``concatenate``, with a third of its cost; the host's
    quaternion functions stack their components so), anything else by ``np.stack``."""
    arrays = list(arrays)
    if axis != -1 or not arrays:
        return np.stack(arrays, axis=axis)
    shape = np.shape(arrays[0])
    for a in arrays:
        if not (type(a) is np.float64 or (type(a) is np.ndarray and a.dtype == np.float64)) or np.shape(a) != shape:
            return np.stack(arrays, axis=axis)
    out = np.empty(shape + (len(arrays),))
    for j, a in enumerate(arrays):
        out[..., j] = a
    return out


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

    def __getattr__(self, name):  # the module's attribute, kept here once read
        value = getattr(self._module, name)
        setattr(self, name, value)
        return value

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
    linalg=_Namespace(np.linalg, norm=_host_norm),
    clip=_host_clip,
    stack=_host_stack,
)
