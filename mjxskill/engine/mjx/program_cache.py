"""The compiled rollout's batched-episode program, kept on disk between processes.

JAX's persistent compilation cache keeps XLA's executables, but each new process still traces and
lowers the whole episode (two nested scans over MJX: about 40 s for push on a 2-core CPU) only to
compute that cache's key. This cache keeps the lowered program itself: ``jax.export``'s
serialized StableHLO (a flatbuffer: data, never Python code or pickle), under a key made of
everything the program depends on: mjxskill's own source, the scenario (its full, validated
content), the MuJoCo model it loads (MJB bytes, after the scenario's timestep and gravity), the
rollout's settings and batch shape, the jax / jaxlib / mujoco / mujoco-mjx versions, the backend
and ``XLA_FLAGS``. A second process reads the program (well under a second), and XLA's compile
of it is what the persistent cache then serves.

Where: ``<mjxskill cache dir>/programs`` (see ``mjxskill._runtime.default_cache_dir``;
``MJXSKILL_CACHE_DIR=off`` turns both caches off). Only single-device runs use it: a batch
sharded over several devices is traced every time (``mjxskill.engine.mjx.sharding``).
Each file holds a header line (the format, the key, and the sha256 of key and program) before
the program: a file whose bytes changed, or that was stored under another key (a copy, a
rename), would run a damaged program or silently another scenario's. Either is detected when
read, reported (``Notice``), traced again and rewritten; so is a file that cannot be read back.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import os
import tempfile
import warnings
from functools import lru_cache
from pathlib import Path
from typing import Callable, NamedTuple

import jax
import jax.export
import mujoco
import numpy as np

from mjxskill._runtime import default_cache_dir
from mjxskill.errors import Notice
from mjxskill.engine.common.types import RolloutOutput
from mjxskill.engine.common.worlds import Worlds

FORMAT = "mjxskill-rollout-program-v2"
PACKAGE_ROOT = Path(__file__).resolve().parents[1]


class Program(NamedTuple):
    """A batched-episode program: ``fn(params (B, P), worlds (B, W)) -> RolloutOutput``.

    origin: "disk" (read back from the cache), "traced" (traced now, and written when the cache is
    on) or "jit" (traced by ``jax.jit`` as usual: several devices). key: the cache key ("" for
    "jit"). XLA's compile comes at the first call of ``fn`` (served by the persistent cache).
    """

    fn: Callable
    origin: str
    key: str


def programs_dir() -> Path | None:
    base = default_cache_dir()
    return None if base is None else base / "programs"


@lru_cache(maxsize=1)
def package_digest() -> str:
    """sha256 of mjxskill's Python source (any edit invalidates every stored program)."""
    h = hashlib.sha256()
    for path in sorted(PACKAGE_ROOT.rglob("*.py")):
        h.update(str(path.relative_to(PACKAGE_ROOT)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "none"


def _model_bytes(model: mujoco.MjModel) -> bytes:
    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


def program_key(identity: str, mj_model: mujoco.MjModel, args) -> str:
    """Hex digest naming the program of a rollout for the argument shapes ``args``. identity:
    what else shapes the program (``Rollout.identity``: scenario, plan, episode settings)."""
    h = hashlib.sha256()
    shapes = [(str(getattr(x, "dtype", type(x))), tuple(np.shape(x))) for x in jax.tree.leaves(args)]
    device = jax.devices()[0]
    parts = (
        FORMAT,
        package_digest(),
        identity,
        repr(shapes),
        repr(jax.tree.structure(args)),
        jax.__version__,
        _version("jaxlib"),
        mujoco.__version__,
        _version("mujoco-mjx"),
        device.platform,
        str(device.device_kind),
        os.environ.get("XLA_FLAGS", ""),
        str(jax.config.jax_enable_x64),  # type: ignore[attr-defined]  # jax.config's stubs omit its flags
    )
    for part in parts:
        h.update(part.encode())
        h.update(b"\0")
    h.update(_model_bytes(mj_model))
    return h.hexdigest()


@lru_cache(maxsize=1)
def _register_pytrees() -> None:
    # Exported programs record their argument and result trees; NamedTuples need a stable name.
    for cls, name in ((Worlds, "mjxskill.engine.mjx.Worlds"), (RolloutOutput, "mjxskill.engine.mjx.RolloutOutput")):
        try:
            jax.export.register_namedtuple_serialization(cls, serialized_name=name)
        except ValueError:  # registered already (a module reload)
            pass


def load_or_trace(identity: str, mj_model: mujoco.MjModel, body: Callable, params, worlds: Worlds) -> Program:
    """The program ``body(params, worlds)`` for these argument shapes: read from disk, or traced
    now (and stored). The rollout keeps what it gets, so this runs once per rollout and shape."""
    _register_pytrees()
    args = (params, worlds)
    key = program_key(identity, mj_model, args)
    directory = programs_dir()
    path = None if directory is None else directory / f"{key}.stablehlo"
    exported, origin = None, "traced"
    if path is not None and path.exists():
        try:
            payload = unpack(path.read_bytes(), key)
            exported, origin = jax.export.deserialize(bytearray(payload)), "disk"
        except Exception as err:  # noqa: BLE001  (damaged, another key's, or from an incompatible jax)
            warnings.warn(f"the cached rollout program {path} cannot be used ({' '.join(str(err).split())[:200]}); "
                          f"tracing it again and replacing the file", Notice, stacklevel=2)
            exported = None
    if exported is None:
        specs = jax.tree.map(lambda x: jax.ShapeDtypeStruct(np.shape(x), x.dtype), args)
        exported = jax.export.export(jax.jit(body))(*specs)
        if path is not None:
            _write_atomically(path, pack(exported.serialize(), key))
    return Program(jax.jit(exported.call), origin, key)


def _digest(key: str, payload: bytes | bytearray) -> str:
    return hashlib.sha256(key.encode() + b"\0" + bytes(payload)).hexdigest()


def pack(payload: bytes | bytearray, key: str) -> bytes:
    """The file content of ``payload`` stored under ``key``: a header line, then the bytes."""
    return f"{FORMAT} {key} {_digest(key, payload)}\n".encode() + bytes(payload)


def unpack(data: bytes, key: str) -> bytes:
    """The program in a file read for ``key``; ValueError unless its header names ``key`` and
    its digest matches its content."""
    header, newline, payload = data.partition(b"\n")
    parts = header.decode("ascii", "replace").split(" ")
    if not newline or len(parts) != 3 or parts[0] != FORMAT:
        raise ValueError(f"not a {FORMAT} file")
    if parts[1] != key:
        raise ValueError(f"it is stored for another key ({parts[1][:12]}..., not {key[:12]}...)")
    if parts[2] != _digest(key, payload):
        raise ValueError("its content does not match its digest (the bytes were changed)")
    return payload


def _write_atomically(path: Path, payload: bytes | bytearray) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            f.write(payload)
        os.replace(tmp, path)
    except OSError:  # read-only cache: the program still runs, it is just not kept
        pass


__all__ = ["Program", "load_or_trace", "pack", "package_digest", "program_key", "programs_dir", "unpack"]
