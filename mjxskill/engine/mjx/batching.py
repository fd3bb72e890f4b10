"""Stepping W worlds at once: one control step (controller + mjx.step) written for one world,
and wrappers that map it over a leading world axis.

Strategies (measured by benchmarks/batching.py, results in benchmarks/RESULTS.md):
  "vmap"    jax.vmap over all worlds: one wide XLA program. Fastest on the CPU once XLA's CPU
            fusion emitters are off (mjxskill/_runtime.py) and the natural choice on GPUs.
  "map"     jax.lax.map: a loop over worlds, one world at a time (small programs, slower).
  "chunked" jax.lax.map with batch_size=chunk: vmap inside chunks, a loop over chunks (bounds
            memory for very large W).
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from mjxskill.engine.mjx.controller import N_ARM, ControllerConfig, ControllerState, impedance_control
from mjxskill.errors import quote

STRATEGIES = ("vmap", "map", "chunked")


_FASTEST = {"cpu": "vmap", "gpu": "vmap", "cuda": "vmap", "tpu": "vmap"}


def default_strategy(backend: str | None = None) -> str:
    """Fastest correct strategy for ``backend`` (default: jax's current one).

    CPU: measured by benchmarks/batching.py (vmap beats lax.map 3-5x at W = 8-64 with the
    fusion-emitter flag off; benchmarks/RESULTS.md). GPU: vmap is what MJX is built for;
    not measured yet on a GPU."""
    backend = jax.default_backend() if backend is None else backend
    return _FASTEST.get(backend, "vmap")


def over_worlds(fn: Callable, strategy: str = "vmap", chunk: int | None = None) -> Callable:
    """Maps ``fn`` (one world; positional pytree arguments) over a leading world axis of all
    its arguments with the given strategy."""
    if strategy == "vmap":
        return jax.vmap(fn)
    if strategy == "map":
        return lambda *args: jax.lax.map(lambda a: fn(*a), args)
    if strategy == "chunked":
        if not chunk or chunk < 1:
            raise ValueError(f"strategy 'chunked' needs chunk >= 1, got chunk={quote(chunk)}")
        return _chunked(jax.vmap(fn), chunk)
    raise ValueError(f"unknown batching strategy {quote(strategy)}; expected one of {STRATEGIES}")


def _chunked(batched_fn: Callable, chunk: int) -> Callable:
    """lax.map over chunks of ``chunk`` worlds, ``batched_fn`` (a vmap) inside each chunk.

    Hand-written instead of ``jax.lax.map(..., batch_size=chunk)``, which (jax 0.10.2) fails
    with ZeroDivisionError on the zero-size leaves MJX data has (e.g. shape (W, 0))."""

    def run(*args):
        n_worlds = jax.tree.leaves(args)[0].shape[0]
        size = min(chunk, n_worlds)
        if n_worlds % size:
            raise ValueError(f"strategy 'chunked': {n_worlds} worlds do not split into chunks of {size}")
        split = lambda x: x.reshape((n_worlds // size, size) + x.shape[1:])  # noqa: E731
        out = jax.lax.map(lambda a: batched_fn(*a), jax.tree.map(split, args))
        return jax.tree.map(lambda x: x.reshape((n_worlds,) + x.shape[2:]), out)

    return run


def control_step(cfg: ControllerConfig, model: mjx.Model, data: mjx.Data, command, nullspace_target,
                 state: ControllerState):
    """One 500 Hz control period of one world: impedance law, then one mjx.step.
    command (19,), nullspace_target (7,). Returns (data, state)."""
    tau, state = impedance_control(cfg, model, data, command, nullspace_target, state)
    ctrl = data.ctrl.at[:N_ARM].set(tau)
    return mjx.step(model, data.replace(ctrl=ctrl)), state


def rollout(cfg: ControllerConfig, model: mjx.Model, data: mjx.Data, state: ControllerState,
            commands, nullspace_target, record: Callable | None = None):
    """lax.scan of control_step over commands (T, 19) for one world. ``record(model, data)``
    picks what to keep per step (default: nothing). Returns (final data, final state, records)."""

    def body(carry, command):
        d, s = carry
        d, s = control_step(cfg, model, d, command, nullspace_target, s)
        return (d, s), (None if record is None else record(model, d))

    (data, state), records = jax.lax.scan(body, (data, state), commands)
    return data, state, records


def put_worlds(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray | None = None,
               mocap_pos: np.ndarray | None = None) -> mjx.Data:
    """Batched MJX data (leading axis W) from per-world qpos (W, nq), qvel (W, nv) and
    mocap_pos (W, nmocap, 3), each run through native mj_forward (no MJX compile)."""
    qpos = np.atleast_2d(qpos)
    device = jax.local_devices()[0]  # this process's, not process 0's (see rollout.compiled)
    worlds = []
    for w in range(qpos.shape[0]):
        data = mujoco.MjData(model)
        data.qpos[:] = qpos[w]
        if qvel is not None:
            data.qvel[:] = qvel[w]
        if mocap_pos is not None:
            data.mocap_pos[:] = mocap_pos[w]
        mujoco.mj_forward(model, data)
        worlds.append(mjx.put_data(model, data, device=device))
    return jax.tree.map(lambda *xs: jnp.stack(xs), *worlds)
