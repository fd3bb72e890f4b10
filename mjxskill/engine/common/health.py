"""Which simulation states an episode may continue from, the same test on both engines.

A world whose state is not finite, whose joints spin faster than ``MAX_QVEL`` or whose free
objects sink below ``MIN_OBJECT_Z`` is marked diverged and frozen at its last good state.
"""

from __future__ import annotations

from mjxskill.engine.common.bindings import FREE
from mjxskill.engine.common.types import MAX_QVEL, MIN_OBJECT_Z


def free_object_z_addresses(bindings) -> tuple[int, ...]:
    """The qpos addresses of the free objects' heights."""
    return tuple(s.qpos_adr + 2 for s in bindings.slots if s.how == FREE)


def healthy_state(xp, qpos, qvel, z_addresses):
    """(...) bool over the leading axes of ``qpos`` (..., nq) and ``qvel`` (..., nv): finite,
    every speed below ``MAX_QVEL``, every free object's height (``z_addresses`` into qpos) above
    ``MIN_OBJECT_Z``. ``xp``: the array namespace (``HOST`` or ``JAX``)."""
    ok = xp.all(xp.isfinite(qpos), axis=-1) & xp.all(xp.isfinite(qvel), axis=-1)
    ok &= xp.all(xp.abs(qvel) < MAX_QVEL, axis=-1)
    for adr in z_addresses:
        ok &= qpos[..., adr] > MIN_OBJECT_Z
    return ok
