"""Unit quaternions (w, x, y, z, MuJoCo's convention), written once for both engines.

Every function takes ``xp``, the array namespace of its values (``mjxskill.engine.common.arrays``:
``JAX`` for the compiled engine, the default, or ``HOST`` for the native engine), and broadcasts
over leading axes. The tests check them against MuJoCo's own ``mju_*`` functions.
"""

from __future__ import annotations

from mjxskill.engine.common.arrays import JAX


def quat_mul(a, b, xp=JAX):
    """Hamilton product a * b; a, b: (..., 4) -> (..., 4)."""
    aw, ax, ay, az = xp.moveaxis(a, -1, 0)
    bw, bx, by, bz = xp.moveaxis(b, -1, 0)
    return xp.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_conj(q, xp=JAX):
    """Conjugate (= inverse of a unit quaternion); q: (..., 4)."""
    q = xp.asarray(q)
    return q * xp.asarray([1.0, -1.0, -1.0, -1.0], dtype=q.dtype)


def quat_normalize(q, xp=JAX):
    return q / xp.linalg.norm(q, axis=-1, keepdims=True)


def quat_to_rotvec(q, xp=JAX):
    """Rotation vector (axis * angle, angle in [0, pi]) of unit quaternion q: (..., 4) -> (..., 3).

    The shorter of the two rotations q and -q is taken. Near the identity the ratio
    angle / sin(angle/2) tends to 2; the masked denominator keeps gradients finite there.
    """
    q = xp.asarray(q)
    q = xp.where(q[..., :1] < 0, -q, q)
    w, v = q[..., 0], q[..., 1:]
    s = xp.linalg.norm(v, axis=-1)
    small = s < 1e-9
    safe_s = xp.where(small, 1.0, s)
    scale = xp.where(small, 2.0 / xp.maximum(w, 1e-12), 2.0 * xp.arctan2(s, w) / safe_s)
    return v * scale[..., None]


def rotvec_to_quat(r, xp=JAX):
    """Unit quaternion of rotation vector r: (..., 3) -> (..., 4)."""
    angle = xp.linalg.norm(r, axis=-1, keepdims=True)
    small = angle < 1e-9
    safe = xp.where(small, 1.0, angle)
    axis_scale = xp.where(small, 0.5, xp.sin(0.5 * safe) / safe)
    return xp.concatenate([xp.cos(0.5 * angle), r * axis_scale], axis=-1)


def quat_angle(a, b, xp=JAX):
    """Angle (rad) of the rotation between unit quaternions a and b: (..., 4) -> (...)."""
    d = xp.abs(xp.inner(a, b))
    return 2.0 * xp.arccos(xp.clip(d, 0.0, 1.0))


def quat_rotate(q, v, xp=JAX):
    """v (..., 3) rotated by unit quaternion q (..., 4): q v q*."""
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * xp.cross(u, v)
    return v + w * t + xp.cross(u, t)
