"""Numba's ``njit`` as the project compiles its loops over a native batch's rows."""

from __future__ import annotations

import numba


def compiled(function):
    """``function`` compiled by numba, its machine code cached on disk beside its module (or in
    numba's cache folder); where no folder can be written (a read-only file system, a full disk
    at the first run) it is compiled at each run instead, never an error: numba refuses to
    decorate a cached function it finds no writable folder for."""
    try:
        return numba.njit(cache=True, nogil=True)(function)
    except RuntimeError:  # "cannot cache function ...: no locator available"
        return numba.njit(nogil=True)(function)
