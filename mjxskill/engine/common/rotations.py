"""Unit-quaternion helpers in JAX (w, x, y, z order, MuJoCo's convention).

Written once here so the controller and the motion generator agree; the tests check them against
MuJoCo's own ``mju_*`` functions.
"""

from __future__ import annotations

import jax.numpy as jnp


def quat_mul(a, b):
    """Hamilton product a * b; a, b: (..., 4) -> (..., 4)."""
    aw, ax, ay, az = jnp.moveaxis(a, -1, 0)
    bw, bx, by, bz = jnp.moveaxis(b, -1, 0)
    return jnp.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_conj(q):
    """Conjugate (= inverse of a unit quaternion); q: (..., 4)."""
    return q * jnp.array([1.0, -1.0, -1.0, -1.0], dtype=q.dtype)


def quat_normalize(q):
    return q / jnp.linalg.norm(q, axis=-1, keepdims=True)


def quat_to_rotvec(q):
    """Rotation vector (axis * angle, angle in [0, pi]) of unit quaternion q: (..., 4) -> (..., 3).

    The shorter of the two rotations q and -q is taken. Near the identity the ratio
    angle / sin(angle/2) tends to 2; the masked denominator keeps gradients finite there.
    """
    q = jnp.where(q[..., :1] < 0, -q, q)
    w, v = q[..., 0], q[..., 1:]
    s = jnp.linalg.norm(v, axis=-1)
    small = s < 1e-9
    safe_s = jnp.where(small, 1.0, s)
    scale = jnp.where(small, 2.0 / jnp.maximum(w, 1e-12), 2.0 * jnp.arctan2(s, w) / safe_s)
    return v * scale[..., None]


def rotvec_to_quat(r):
    """Unit quaternion of rotation vector r: (..., 3) -> (..., 4)."""
    angle = jnp.linalg.norm(r, axis=-1, keepdims=True)
    small = angle < 1e-9
    safe = jnp.where(small, 1.0, angle)
    axis_scale = jnp.where(small, 0.5, jnp.sin(0.5 * safe) / safe)
    return jnp.concatenate([jnp.cos(0.5 * angle), r * axis_scale], axis=-1)


def quat_angle(a, b):
    """Angle (rad) of the rotation between unit quaternions a and b: (..., 4) -> (...)."""
    d = jnp.abs(jnp.sum(a * b, axis=-1))
    return 2.0 * jnp.arccos(jnp.clip(d, 0.0, 1.0))


def quat_rotate(q, v):
    """v (..., 3) rotated by unit quaternion q (..., 4): q v q*."""
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * jnp.cross(u, v)
    return v + w * t + jnp.cross(u, t)
