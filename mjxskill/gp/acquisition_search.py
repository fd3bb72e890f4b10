"""The acquisition's search: the best point of an acquisition in the unit cube, from random
candidates (some on the cube's bounds) refined by projected Adam. Pure and jittable; run it
with x64 enabled."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax

from mjxskill.gp.settings import AcquisitionSettings


def raw_candidates(key, d: int, settings: AcquisitionSettings) -> jnp.ndarray:
    """(n_raw, d) random candidates in [0, 1]^d: uniform, and a share ``raw_bounds_share`` of
    them drawn uniformly in [-0.5, 1.5]^d and clipped, so that each of their coordinates lies on
    a bound with probability 1/2. Where the parameter bounds are active on the front (a force at
    its limit, a motion at the workspace's edge; VehicleSafety's front lies on the cube's faces
    and edges), the improvement is confined to faces of the cube that uniform candidates never
    reach, and Adam from the best of those stops at a local optimum short of them (RESULTS.md,
    "Candidates on the bounds")."""
    n_bounds = round(settings.raw_bounds_share * settings.n_raw)  # static
    if n_bounds == 0:
        return jax.random.uniform(key, (settings.n_raw, d), jnp.float64)
    k_inner, k_bounds = jax.random.split(key)
    inner = jax.random.uniform(k_inner, (settings.n_raw - n_bounds, d), jnp.float64)
    on_bounds = jnp.clip(jax.random.uniform(k_bounds, (n_bounds, d), jnp.float64, -0.5, 1.5), 0.0, 1.0)
    return jnp.concatenate([inner, on_bounds], axis=0)


def maximize(acq, key, d: int, settings: AcquisitionSettings) -> jnp.ndarray:
    """Best point in [0, 1]^d: random candidates, then projected Adam from the best ones."""
    raw = raw_candidates(key, d, settings)
    raw_vals = acq(raw)
    _, top = jax.lax.top_k(raw_vals, settings.n_restarts)
    x0 = raw[top]
    # Adam's steps stay ~learning_rate long near an optimum; a cosine decay to
    # final_learning_rate lets the starts settle (fronts along steep edges need ~1e-3 precision).
    lr = optax.cosine_decay_schedule(settings.learning_rate, settings.n_opt_steps,
                                     settings.final_learning_rate / settings.learning_rate)
    opt = optax.adam(lr)
    # Starts are independent: the gradient of the sum is each start's own gradient.
    def loss(xs):
        return -jnp.sum(acq(xs))

    def step(carry, _):
        xs, s = carry
        g = jax.grad(loss)(xs)
        g = jnp.where(jnp.isfinite(g), g, 0.0)
        upd, s = opt.update(g, s, xs)
        return (jnp.clip(optax.apply_updates(xs, upd), 0.0, 1.0), s), None

    (xs, _), _ = jax.lax.scan(step, (x0, opt.init(x0)), None, length=settings.n_opt_steps)
    cand = jnp.concatenate([xs, raw[top[:1]]], axis=0)
    vals = acq(cand)
    return cand[jnp.argmax(vals)]


__all__ = ["maximize", "raw_candidates"]
