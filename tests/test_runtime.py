"""The package's process-wide JAX settings (mjxskill/_runtime.py)."""

import os
import subprocess
import sys

from mjxskill._runtime import (COLLECTIVE_TERMINATE_SETTING, COLLECTIVE_WARN_SETTING, CPU_FUSION_SETTING, CPU_SETTINGS,
                               YNN_FUSION_SETTING, configure_xla_flags, with_host_devices)

DEFAULTS = " ".join(setting for _, setting in CPU_SETTINGS)


def test_flag_added_to_empty_environment():
    env = {}
    assert configure_xla_flags(env) == DEFAULTS == (f"{CPU_FUSION_SETTING} {YNN_FUSION_SETTING} "
                                                    f"{COLLECTIVE_TERMINATE_SETTING} {COLLECTIVE_WARN_SETTING}")
    assert env["XLA_FLAGS"] == DEFAULTS


def test_user_flags_are_kept():
    env = {"XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    configure_xla_flags(env)
    assert env["XLA_FLAGS"] == f"--xla_force_host_platform_device_count=2 {DEFAULTS}"


def test_user_choice_of_the_same_flag_wins():
    env = {"XLA_FLAGS": "--xla_cpu_use_fusion_emitters=true"}
    configure_xla_flags(env)
    rest = f"{COLLECTIVE_TERMINATE_SETTING} {COLLECTIVE_WARN_SETTING}"
    assert env["XLA_FLAGS"] == f"--xla_cpu_use_fusion_emitters=true {YNN_FUSION_SETTING} {rest}"
    env = {"XLA_FLAGS": "--xla_cpu_experimental_ynn_fusion_type=reduce"}
    configure_xla_flags(env)
    assert env["XLA_FLAGS"] == f"--xla_cpu_experimental_ynn_fusion_type=reduce {CPU_FUSION_SETTING} {rest}"
    env = {"XLA_FLAGS": "--xla_cpu_collective_call_terminate_timeout_seconds=60"}
    configure_xla_flags(env)
    assert env["XLA_FLAGS"].split()[0] == "--xla_cpu_collective_call_terminate_timeout_seconds=60"
    assert COLLECTIVE_TERMINATE_SETTING not in env["XLA_FLAGS"]


def test_host_devices_replace_or_keep_the_users_count_and_leave_other_flags():
    flags = f"--a {CPU_FUSION_SETTING} --xla_force_host_platform_device_count=4"
    assert with_host_devices(flags, 2) == f"--a {CPU_FUSION_SETTING} --xla_force_host_platform_device_count=2"
    assert with_host_devices(flags, 2, keep_users=True) == flags
    assert with_host_devices("", 3) == "--xla_force_host_platform_device_count=3"


def _run(code: str, **extra_env) -> str:
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_COMPILATION_CACHE_DIR")}
    env.update(extra_env)
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout


def test_flag_in_effect_in_a_fresh_process_and_importing_creates_nothing(tmp_path):
    cache = tmp_path / "cache"
    out = _run(
        "import mjxskill, os, jax, jax.numpy as jnp\n"
        "jnp.ones(3).block_until_ready()\n"
        "print(os.environ['XLA_FLAGS']); print(jax.config.jax_compilation_cache_dir)",
        MJXSKILL_CACHE_DIR=str(cache), XDG_CACHE_HOME=str(tmp_path / "xdg"),
    )
    flags, cache_dir = out.split("\n")[:2]
    assert CPU_FUSION_SETTING in flags and YNN_FUSION_SETTING in flags.split()
    assert COLLECTIVE_TERMINATE_SETTING in flags.split()  # and this jaxlib knows the flags (else: abort)
    assert cache_dir == "None"  # the import switched no cache on
    assert not cache.exists() and not (tmp_path / "xdg").exists()  # and created no directory


def test_the_cache_is_switched_on_where_compiling_starts_even_after_a_compile(tmp_path):
    # A jit compile before the cache is enabled makes jax decide "no cache"; enabling it later
    # (as compile_rollout does) must still make the next compiles persistent.
    out = _run(
        "import mjxskill, jax, jax.numpy as jnp\n"
        "jax.jit(lambda x: x + 1)(jnp.ones(3)).block_until_ready()\n"
        "from mjxskill._runtime import enable_compilation_cache\n"
        "print(enable_compilation_cache()); print(enable_compilation_cache())\n"
        "jax.jit(lambda x: jnp.sin(x) * 2)(jnp.ones(300)).block_until_ready()\n"
        "print(jax.config.jax_compilation_cache_dir)",
        MJXSKILL_CACHE_DIR=str(tmp_path), JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0",
    )
    first, second, cache_dir = out.split("\n")[:3]
    assert first == second == cache_dir == str(tmp_path)
    assert any(tmp_path.iterdir()), "nothing was written to the persistent cache"


def test_cache_can_be_turned_off():
    out = _run(
        "import mjxskill, jax\nfrom mjxskill._runtime import enable_compilation_cache\n"
        "print(enable_compilation_cache()); print(jax.config.jax_compilation_cache_dir)",
        MJXSKILL_CACHE_DIR="off",
    )
    assert out.split() == ["None", "None"]
