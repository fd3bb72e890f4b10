"""Splitting a batch of independent episodes over the local devices (``jax.sharding``).

The compiled rollout flattens its B x W episodes into one batch axis; ``shard_batch`` splits that
axis over a 1-D device mesh with ``jax.shard_map``: every device runs the same per-world program
(vmapped) on its own slice, and no data crosses devices, so results equal the single-device ones
(the per-world program does not depend on which other worlds share its batch).

On a CPU host, ``XLA_FLAGS=--xla_force_host_platform_device_count=N`` (set before jax starts)
makes N host devices; each runs its shard on its own thread, so sharding is how a vmapped rollout
uses more than one core. On GPUs it spreads the batch over all local GPUs. Across hosts, see the
docs/engines.md, "Scaling" (each process rolls out its own share with ``jax.distributed``).
"""

from __future__ import annotations

from typing import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec

BATCH_AXIS = "batch"


def batch_mesh(devices: Sequence[jax.Device] | None = None) -> Mesh:
    """A 1-D mesh with axis ``"batch"`` over ``devices`` (default: all local devices)."""
    devices = list(jax.local_devices() if devices is None else devices)
    if not devices:
        raise ValueError("batch_mesh needs at least one device")
    return Mesh(np.asarray(devices), (BATCH_AXIS,))


def _pad(x: jax.Array, size: int) -> jax.Array:
    """x with its leading axis padded to ``size`` by repeating its last row (a valid input, so
    padded episodes run normally and are dropped afterwards)."""
    extra = size - x.shape[0]
    return x if extra == 0 else jnp.concatenate([x, jnp.repeat(x[-1:], extra, axis=0)], axis=0)


def shard_batch(fn: Callable, devices: Sequence[jax.Device] | None = None) -> Callable:
    """Wraps ``fn`` (positional pytree arguments, all with the same leading batch size N; returns
    a pytree whose leaves have leading size N) so that the batch is split over ``devices``
    (default: all local devices) on a 1-D mesh.

    N need not be a multiple of the device count: the batch is padded (repeating its last row) and
    the padding is dropped from the outputs. With one device, ``fn`` is returned as it is.
    Traceable: call it inside ``jax.jit``.
    """
    mesh = batch_mesh(devices)
    n_devices = mesh.size
    if n_devices == 1:
        return fn

    def sharded(*args):
        sizes = {x.shape[0] for x in jax.tree.leaves(args)}
        if len(sizes) != 1:
            raise ValueError(f"shard_batch: every argument needs the same leading batch size, got sizes {sorted(sizes)}")
        (size,) = sizes
        padded = -(-size // n_devices) * n_devices
        args = jax.tree.map(lambda x: _pad(x, padded), args)
        spec = PartitionSpec(BATCH_AXIS)
        # check_vma=False: MJX's solver has lax.cond branches that mix per-device and
        # replicated values, which shard_map's varying-axes type check rejects; every value
        # here is per-device anyway (nothing is reduced across the mesh).
        out = jax.shard_map(fn, mesh=mesh, in_specs=(spec,) * len(args), out_specs=spec, check_vma=False)(*args)
        return jax.tree.map(lambda x: x[:size], out)

    return sharded
