"""The package's process-wide JAX settings (mjxskill/_runtime.py)."""

import os
import subprocess
import sys

from mjxskill._runtime import CPU_FUSION_SETTING, configure_xla_flags


def test_flag_added_to_empty_environment():
    env = {}
    assert configure_xla_flags(env) == CPU_FUSION_SETTING
    assert env["XLA_FLAGS"] == CPU_FUSION_SETTING


def test_user_flags_are_kept():
    env = {"XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    configure_xla_flags(env)
    assert env["XLA_FLAGS"] == f"--xla_force_host_platform_device_count=2 {CPU_FUSION_SETTING}"


def test_user_choice_of_the_same_flag_wins():
    env = {"XLA_FLAGS": "--xla_cpu_use_fusion_emitters=true"}
    configure_xla_flags(env)
    assert env["XLA_FLAGS"] == "--xla_cpu_use_fusion_emitters=true"


def _run(code: str, **extra_env) -> str:
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_COMPILATION_CACHE_DIR")}
    env.update(extra_env)
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout


def test_flag_in_effect_in_a_fresh_process(tmp_path):
    # The flag must reach XLA's CPU client: the debug options dump shows what XLA parsed.
    out = _run(
        "import mjxskill, os, jax, jax.numpy as jnp\n"
        "jnp.ones(3).block_until_ready()\n"
        "print(os.environ['XLA_FLAGS']); print(jax.config.jax_compilation_cache_dir)",
        MJXSKILL_CACHE_DIR=str(tmp_path),
    )
    flags, cache = out.split("\n")[:2]
    assert CPU_FUSION_SETTING in flags
    assert cache == str(tmp_path)


def test_cache_can_be_turned_off():
    out = _run("import mjxskill, jax; print(jax.config.jax_compilation_cache_dir)", MJXSKILL_CACHE_DIR="off")
    assert out.strip() == "None"
