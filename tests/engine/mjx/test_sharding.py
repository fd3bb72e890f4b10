"""Sharding of a batch over local devices (mjxskill/engine/mjx/sharding.py).

Run in fresh subprocesses: the host device count (``--xla_force_host_platform_device_count``)
must be in XLA_FLAGS before jax starts (mjxskill appends its own CPU flag to them). The compiled
rollout itself is checked on 1 and 2 devices by benchmarks/throughput.py (column "equal to 1
device"); compiling it twice more here would cost minutes.
"""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def _run(code: str, devices: int) -> str:
    env = dict(os.environ)
    env["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={devices}"
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=env, capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout  # (importing MJX may print a line about optional backends first)


# A per-world program with a scan, a pytree argument and a pytree result; the sharded call must
# equal the unsharded one bit for bit (no data crosses devices) for every batch size, including
# sizes that are not multiples of the device count (padding).
SCRIPT = """
import mjxskill, os, jax, jax.numpy as jnp, numpy as np
from mjxskill.engine.mjx.sharding import shard_batch, batch_mesh

assert jax.local_device_count() == 2, jax.devices()
assert "--xla_cpu_use_fusion_emitters=false" in os.environ["XLA_FLAGS"]

def world(x0, p):
    def step(x, _):
        x = x + 0.01 * (p["k"] * jnp.sin(x) - p["d"] * x)
        return x, jnp.sum(x)
    x, trace = jax.lax.scan(step, x0, None, length=50)
    return {"x": x, "total": jnp.sum(trace)}

batched = jax.vmap(world)
plain, sharded = jax.jit(batched), jax.jit(shard_batch(batched))
for n in (1, 2, 5, 8):
    key = jax.random.key(n)
    x0 = jax.random.normal(key, (n, 3))
    p = {"k": jnp.linspace(0.5, 2.0, n), "d": jnp.linspace(0.1, 0.3, n)}
    a, b = plain(x0, p), sharded(x0, p)
    for name in a:
        assert b[name].shape == a[name].shape, (n, name)
        np.testing.assert_array_equal(np.asarray(b[name]), np.asarray(a[name]))
    if n % 2 == 0:
        assert len(b["x"].sharding.device_set) == 2, b["x"].sharding
print("ok", batch_mesh().shape)
"""


def test_sharded_batch_equals_single_device_on_two_host_devices():
    assert _run(SCRIPT, devices=2).splitlines()[-1].split()[0] == "ok"


def test_one_device_leaves_the_function_alone():
    out = _run(
        """
        import mjxskill, jax
        from mjxskill.engine.mjx.sharding import shard_batch
        f = jax.vmap(lambda x: x * 2)
        print(shard_batch(f) is f)
        """,
        devices=1,
    )
    assert out.strip().splitlines()[-1] == "True"


def test_unequal_batch_sizes_are_rejected():
    out = _run(
        """
        import mjxskill, jax, jax.numpy as jnp
        from mjxskill.engine.mjx.sharding import shard_batch
        f = shard_batch(jax.vmap(lambda a, b: a + b))
        try:
            f(jnp.ones(3), jnp.ones(4))
        except ValueError as e:
            print(e)
        """,
        devices=2,
    )
    assert "same leading batch size" in out and "[3, 4]" in out


def test_the_rollout_routes_its_batch_through_shard_map():
    # Lowering (no compile) a one-tick rollout on 2 devices: its program is partitioned.
    out = _run(
        """
        import mjxskill, jax, numpy as np
        from mjxskill import load_scenario, compile_rollout
        r = compile_rollout(load_scenario("push"), worlds=3, episode_seconds=0.1)
        worlds = r.sample_worlds(jax.random.key(0), 1)
        params = jax.numpy.zeros((1, 4))
        program = r.program(params, worlds)
        assert program.origin == "jit"
        text = program.fn.lower(params, worlds).as_text()
        print("sdy.manual_computation" in text)  # the shard_map region
        """,
        devices=2,
    )
    assert out.strip().splitlines()[-1] == "True"
