"""The persistent compilation cache (mjxskill/_runtime.py): a second process reuses what the
first compiled. Asserted on JAX's cache-hit events and on the cache's files, not on wall-clock
(benchmarks/throughput.py --cache-check measures the time saved on the real rollout)."""

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import json, mjxskill, jax, jax.numpy as jnp
import jax.monitoring
from mjxskill._runtime import enable_compilation_cache
enable_compilation_cache()  # as compile_rollout and the commands do
hits = []
jax.monitoring.register_event_listener(
    lambda event, **kw: hits.append(event) if event == "/jax/compilation_cache/cache_hits" else None)

@jax.jit
def f(x):
    def step(c, _):
        return jnp.tanh(c @ c.T) + 0.5 * c, None
    return jax.lax.scan(step, x, None, length=20)[0].sum()

f(jnp.eye(4)).block_until_ready()
print(json.dumps({"hits": len(hits), "cache_dir": jax.config.jax_compilation_cache_dir}))
"""


def _process(cache: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_") and k != "XLA_FLAGS"}
    env["MJXSKILL_CACHE_DIR"] = str(cache)
    env["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = "0"  # cache even this small function
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_second_process_hits_the_cache(tmp_path):
    first = _process(tmp_path)
    assert first["cache_dir"] == str(tmp_path)
    assert first["hits"] == 0
    files = sorted(p.name for p in tmp_path.iterdir())
    assert any("jit_f" in name for name in files), files
    second = _process(tmp_path)
    assert second["hits"] >= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == files  # nothing new was compiled
