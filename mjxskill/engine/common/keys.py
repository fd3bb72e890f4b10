"""The PRNG keys the worlds are drawn from: a seed's key folded with one number after another
(a stream, then e.g. a batch or a round), so that each use of a seed draws worlds of its own and
a resumed run draws the same ones. Imports jax only when a key is made: the commands' --help and
bad-input errors import the modules that draw worlds (training's loop, the race, the validation).
"""

from __future__ import annotations


def stream_key(seed: int, *folds: int):
    """``jax.random.PRNGKey(seed)`` folded with each of ``folds`` in turn (``jax.random.fold_in``)."""
    import jax  # lazy: ~1 s, and the commands' --help and bad-input errors import this module's callers

    key = jax.random.PRNGKey(seed)
    for value in folds:
        key = jax.random.fold_in(key, value)
    return key


__all__ = ["stream_key"]
