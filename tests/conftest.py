"""Shared test settings.

mjxskill is imported first so that its XLA CPU flag and the persistent compilation cache are in
place before any test touches JAX. Expensive compiled functions are session fixtures in the
test modules that need them (compiling MJX code costs seconds to tens of seconds).
"""

import mjxskill  # noqa: F401  (side effect: XLA flags and compilation cache)

import jax

jax.config.update("jax_enable_x64", False)
