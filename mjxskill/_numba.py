"""Numba's ``njit`` as the project compiles its loops over a native batch's rows."""

from __future__ import annotations

import numba


def compiled(function):
    """``function`` compiled by numba, its machine code cached on disk beside its module (or in
    numba's cache folder); where no folder can be written (a read-only file system, a full disk
    at the first run) it is compiled at each run instead, never an error: numba refuses to
    decorate a cached function it finds no writable folder for.

    Divisions follow IEEE as numpy's do (``error_model="numpy"``): Python's model tests every
    divisor for zero and branches to raise, which costs the law ~10 % of its time, and an
    exception could not leave MuJoCo's control callback anyway (the kernels' divisors are
    positive where they divide). numba's cache is keyed by a module's source, not by these
    options: after changing them, delete the ``__pycache__/*.nbi``/``*.nbc`` files (or touch the
    kernels' modules), or the code measured is the code compiled before."""
    options = dict(nogil=True, error_model="numpy")
    try:
        return numba.njit(cache=True, **options)(function)
    except RuntimeError:  # "cannot cache function ...: no locator available"
        return numba.njit(**options)(function)
