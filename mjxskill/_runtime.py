"""Process-wide JAX settings that must be in place before JAX creates a backend.

XLA's CPU *fusion emitters* make ``jax.vmap`` over MJX kinematics about 2000x slower: a
vmapped rollout of a 7-DOF arm (``lax.scan`` of ``mjx.step``, batch 8) ran at 17 control
steps/s with them and at 33,600 with ``--xla_cpu_use_fusion_emitters=false``, and compiled
in 50 s instead of 8 s; results agree to float32 rounding (jax 0.10.2, mujoco 4.0.0,
mujoco-mjx 3.17.0 on the project's 2-core CPU; seen on jax 0.7.2 through 0.10.2, not on
0.6.2; ``benchmarks/NOTES.md``, section "14. XLA's CPU fusion emitters: vmapped MJX ~2000x
slower"). XLA reads ``XLA_FLAGS`` once, when jax creates its CPU client, so the flag must be
in the environment before that: ``mjxskill/__init__.py`` calls :func:`configure_xla_flags`
on import, before any of its modules imports jax. The flag concerns XLA's CPU backend
only: computations on a GPU are unaffected.

XLA's CPU *YNN fusion* hangs calls of a few hundred MJX episodes: a call of 6 sets x 60 worlds
(push, 0.1 or 0.4 s episodes) sat at 0 % CPU past its 240-300 s timeout, every XLA thread
parked, and finished (137 s under load 6.8, compile included) with
``--xla_cpu_experimental_ynn_fusion_type=`` (no fusion types), which ``configure_xla_flags``
therefore sets too. It is jax issue 39257 (jaxlib 0.10.2 and 0.11.0 on x86-64 Linux: rank-7/8
broadcast-multiply-reduce kernels); ``benchmarks/NOTES.md``, section "13. Found on the way:
large MJX calls on the CPU never finish", has the evidence.

Compiling MJX code costs tens of seconds on a 2-core CPU, so the persistent compilation
cache is on by default (``MJXSKILL_CACHE_DIR`` moves it, ``MJXSKILL_CACHE_DIR=off`` turns it
off). It is switched on where compiling starts (``compile_rollout``) and by the commands
(``mjxskill.cli.run``), not by importing the package, which creates no directory.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

from mjxskill.errors import Notice, quote

CPU_FUSION_FLAG = "--xla_cpu_use_fusion_emitters"
CPU_FUSION_SETTING = f"{CPU_FUSION_FLAG}=false"
YNN_FUSION_FLAG = "--xla_cpu_experimental_ynn_fusion_type"
YNN_FUSION_SETTING = f"{YNN_FUSION_FLAG}="
# XLA's CPU collectives (MJX calls over several host devices) end the process when one device
# reaches a collective this long before the other (default 40 s; the warning: 20 s). A
# device's share of a long call can finish minutes before the other's (vmapped collision
# loops run as long as their slowest world), and the peg's agreement (550 episodes in calls of
# 120) was killed so after 41 minutes of work (benchmarks/NOTES.md, section 19): an hour, a warning
# after five minutes.
COLLECTIVE_TERMINATE_FLAG = "--xla_cpu_collective_call_terminate_timeout_seconds"
COLLECTIVE_TERMINATE_SETTING = f"{COLLECTIVE_TERMINATE_FLAG}=3600"
COLLECTIVE_WARN_FLAG = "--xla_cpu_collective_call_warn_stuck_timeout_seconds"
COLLECTIVE_WARN_SETTING = f"{COLLECTIVE_WARN_FLAG}=300"
# what configure_xla_flags adds, each unless the user set that flag
CPU_SETTINGS = ((CPU_FUSION_FLAG, CPU_FUSION_SETTING), (YNN_FUSION_FLAG, YNN_FUSION_SETTING),
                (COLLECTIVE_TERMINATE_FLAG, COLLECTIVE_TERMINATE_SETTING), (COLLECTIVE_WARN_FLAG, COLLECTIVE_WARN_SETTING))
HOST_DEVICES_FLAG = "--xla_force_host_platform_device_count"


def with_host_devices(flags: str, devices: int, *, keep_users: bool = False) -> str:
    """``XLA_FLAGS`` ``flags`` asking for ``devices`` CPU host devices (how a vmapped MJX rollout
    uses more than one core; read only when jax starts its CPU client). A host-device setting
    already in ``flags`` is replaced, or kept when ``keep_users``; other flags stay."""
    if keep_users and HOST_DEVICES_FLAG in flags:
        return flags
    kept = [f for f in flags.split() if not f.startswith(HOST_DEVICES_FLAG)]
    return " ".join([*kept, f"{HOST_DEVICES_FLAG}={devices}"])


def configure_xla_flags(environ: "os._Environ[str] | dict[str, str]" = os.environ) -> str:
    """Adds ``--xla_cpu_use_fusion_emitters=false``, ``--xla_cpu_experimental_ynn_fusion_type=``
    and the CPU collectives' timeouts to ``XLA_FLAGS`` (``CPU_SETTINGS``), each unless the user
    set that flag.

    A user's own setting of either flag (any value) wins; other flags are kept as they are.
    When ``environ`` is ``os.environ``, also sets ``OPENBLAS_NUM_THREADS=1`` unless it is set.
    Returns the resulting ``XLA_FLAGS`` string.
    """
    # Single-threaded BLAS for the GP's LAPACK calls: on small shared machines OpenBLAS's thread
    # pool spins against other processes and makes a 448 x 448 Cholesky take from 2 to 700 ms
    # (benchmarks/RESULTS.md, "Optimizer overhead"); XLA has its own thread pool for the
    # rollouts. A user's own setting wins.
    if environ is os.environ:
        environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    flags = environ.get("XLA_FLAGS", "")
    for flag, setting in CPU_SETTINGS:
        if flag not in flags:
            flags = f"{flags} {setting}".strip()
    environ["XLA_FLAGS"] = flags
    if "jax" in sys.modules and environ is os.environ:
        # The flag is read when the CPU client is created, which is lazy: importing jax
        # earlier is fine as long as no computation ran yet. We cannot detect that cheaply,
        # so only warn when a backend is already live.
        try:
            # lazy: jax is imported already here; importing it at the top would start it first
            from jax._src import xla_bridge

            if xla_bridge.backends_are_initialized():
                warnings.warn(
                    "mjxskill was imported after JAX initialised its backends; "
                    f"{CPU_FUSION_SETTING} may not be in effect and CPU rollouts can be "
                    "orders of magnitude slower. Import mjxskill first or export "
                    f"XLA_FLAGS={CPU_FUSION_SETTING}.",
                    RuntimeWarning,
                    stacklevel=3,
                )
        except Exception:  # private API moved: the warning is a courtesy only
            pass
    return flags


_warned: set[str] = set()


def _warn_once(message: str) -> None:
    """A ``Notice`` (the command line prints it as one warning line), once per process."""
    if message not in _warned:
        _warned.add(message)
        warnings.warn(message, Notice, stacklevel=3)


def default_cache_dir() -> Path | None:
    """Where compiled XLA executables are kept between processes (None: cache off)."""
    setting = os.environ.get("MJXSKILL_CACHE_DIR")
    if setting is not None:
        return None if setting.strip().lower() in ("", "0", "off", "none", "false") else Path(setting)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "mjxskill" / "jax"


def enable_compilation_cache(path: Path | None = None) -> Path | None:
    """Turns on JAX's persistent compilation cache (idempotent; called by ``compile_rollout``
    and the commands).

    Done through JAX's own environment variables when jax is not imported yet, so that
    commands that never touch JAX (``mjxskill.plan``) stay cheap, and a user's own
    ``JAX_COMPILATION_CACHE_DIR`` wins.
    """
    path = default_cache_dir() if path is None else path
    if path is None:
        return None
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:  # read-only home, or the setting names a file: run without a cache
        why = "it is a file" if path.exists() and not path.is_dir() else err.strerror
        _warn_once(f"the compile cache {quote(str(path), 300)} is not a usable directory ({why}); compile caches "
                   f"are off, so every run compiles from scratch (set MJXSKILL_CACHE_DIR to a directory, or off)")
        return None
    settings = {
        "JAX_COMPILATION_CACHE_DIR": (str(path), str),
        # Cache everything that took noticeable time; MJX steps take seconds to compile.
        "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": ("0.5", float),
        "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES": ("0", int),
    }
    for name, (value, _) in settings.items():
        os.environ.setdefault(name, value)
    if "jax" in sys.modules:  # jax read its environment already: tell it directly
        import jax  # lazy: only when jax is imported already (plan never imports it; the flags come first)

        # jax.config's stubs omit its flags
        if jax.config.jax_compilation_cache_dir != os.environ["JAX_COMPILATION_CACHE_DIR"]:  # type: ignore[attr-defined]
            for name, (_, parse) in settings.items():
                jax.config.update(name.lower(), parse(os.environ[name]))
            try:  # a compile before this point decided "no cache" once and for all: decide again
                from jax._src import compilation_cache  # lazy: as jax above

                compilation_cache.reset_cache()
            except (ImportError, AttributeError):  # private API moved: the cache may stay off
                pass
    return Path(os.environ["JAX_COMPILATION_CACHE_DIR"])


_KNOWN_GOOD = {setting for _, setting in CPU_SETTINGS}
_checked: dict[str, str | None] = {}


def xla_flags_problem(flags: str | None = None) -> str | None:
    """Why XLA would abort on ``XLA_FLAGS`` (None: it would not), found before jax reads them:
    XLA ends the process with a fatal line of its own on an unknown flag or a bad value, which
    no ``try`` catches. A token that is not ``--name`` or ``--name=value`` is refused by its
    shape; flags beyond mjxskill's own are tried once in a child process (about a second),
    whose fatal line names the bad token."""
    flags = os.environ.get("XLA_FLAGS", "") if flags is None else flags
    if flags in _checked:
        return _checked[flags]
    problem = None
    tokens = flags.split()
    bad = next((t for t in tokens if not re.fullmatch(r"--[A-Za-z][A-Za-z0-9_]*(=\S*)?", t)), None)
    if bad is not None:
        problem = f"XLA_FLAGS: {bad[:60]!r} is not an XLA flag (--name or --name=value)"
    elif any(t not in _KNOWN_GOOD and not re.fullmatch(rf"{HOST_DEVICES_FLAG}=[1-9][0-9]*", t) for t in tokens):
        env = dict(os.environ, XLA_FLAGS=flags, JAX_PLATFORMS="cpu")
        try:
            probe = subprocess.run([sys.executable, "-c", "import jax; jax.devices('cpu')"], env=env,
                                   capture_output=True, text=True, timeout=300)
        except (OSError, subprocess.TimeoutExpired):
            probe = None  # cannot tell: jax will say
        if probe is not None and probe.returncode != 0 and "XLA_FLAGS" in probe.stderr + flags:
            unknown = re.search(r"Unknown flag in XLA_FLAGS: (\S+)", probe.stderr)
            value = re.search(r"Couldn't interpret value (.*) for flag (\w+)", probe.stderr)
            if unknown:
                problem = f"XLA_FLAGS: {unknown.group(1)[:60]!r} is not a flag XLA knows"
            elif value:
                token = next((t for t in tokens if t.startswith(f"--{value.group(2)}=")), value.group(2))
                problem = f"XLA_FLAGS: {token[:60]!r} has a value XLA cannot read"
            elif "parse_flags_from_env" in probe.stderr:
                problem = "XLA_FLAGS: XLA refuses them (" + probe.stderr.strip().splitlines()[0][-120:] + ")"
    _checked[flags] = problem
    return problem
