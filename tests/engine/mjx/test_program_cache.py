"""The on-disk program cache (mjxskill/engine/mjx/program_cache.py): a second process reads the
lowered rollout instead of tracing it and computes bit-identical results; a damaged file is
traced again (on a tiny program); anything the program depends on changes its key. Asserted on
the program's origin and the files, not on wall-clock (benchmarks/throughput.py --cache-check
times it)."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjxskill import compile_rollout, load_scenario
from mjxskill.engine.mjx.program_cache import program_key
from scenario_texts import library_text, write_library_copy

ROOT = Path(__file__).resolve().parents[3]

SCRIPT = """
import json, sys, mjxskill, jax, numpy as np
from mjxskill import compile_rollout, load_scenario
from mjxskill.task import plan_task
scn = load_scenario("peg_square")
r = compile_rollout(scn, worlds=2, episode_seconds=0.3)
params = np.tile(plan_task(scn).defaults, (2, 1)).astype(np.float32)
params[1, 0] = -8.0
worlds = r.sample_worlds(jax.random.key(0), 2)
out = r.run_worlds(params, worlds)
program = r.program(jax.numpy.asarray(params), worlds)
print(json.dumps({"origin": program.origin, "key": program.key,
                  "objectives": np.asarray(out.objectives).tolist(),
                  "metrics": {k: np.asarray(v).tolist() for k, v in out.metrics.items()}}))
"""


def _process(cache: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_") and k != "XLA_FLAGS"}
    env["MJXSKILL_CACHE_DIR"] = str(cache)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_second_process_reads_the_program_and_computes_the_same(tmp_path):
    first = _process(tmp_path)
    assert first["origin"] == "traced"
    stored = tmp_path / "programs" / f"{first['key']}.stablehlo"
    assert stored.is_file() and stored.stat().st_size > 0
    second = _process(tmp_path)
    assert second["origin"] == "disk" and second["key"] == first["key"]
    assert second["objectives"] == first["objectives"] and second["metrics"] == first["metrics"]  # bit-identical
    # A damaged file is traced again and rewritten: the next test, on a tiny program (a third
    # process here would trace the whole peg episode again, about 40 s, for the same code path).


def _key(scn, seconds=0.3, batch=2, worlds=2):
    r = compile_rollout(scn, worlds=worlds, episode_seconds=seconds)
    params = jnp.zeros((batch, len(r.parameter_names)), jnp.float32)
    w = r.sample_worlds(jax.random.key(0), batch)
    return program_key(r.identity(), r.mj_model, (params, w))


def test_the_key_names_everything_the_program_depends_on():
    peg = load_scenario("peg_square")
    base = _key(peg)
    assert _key(peg) == base  # deterministic
    assert _key(load_scenario("peg_square")) == base  # the same content loaded again
    others = [_key(peg, seconds=0.4), _key(peg, batch=3), _key(peg, worlds=3), _key(load_scenario("push")),
              _key(load_scenario("peg"))]  # the round peg: another MuJoCo model
    assert len({base, *others}) == 6
    # The scenario's content counts, the skill library it includes too: the same files with
    # another insertion threshold (a tree constant, not in the MuJoCo model) get another key.
    old = "threshold: {type: float, unit: m, default: 0.04}"
    library = library_text()
    assert library.count(old) == 1
    folder = Path(os.environ.get("TMPDIR", "/tmp")) / f"peg-key-{os.getpid()}"
    folder.mkdir(exist_ok=True)
    try:
        same = _key(load_scenario(str(write_library_copy(folder, "peg_square", library))))
        changed = write_library_copy(folder, "peg_square", library.replace(old, old.replace("default: 0.04", "default: 0.045")))
        assert _key(load_scenario(str(changed))) != same
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    np.testing.assert_equal(len(base), 64)


def _tiny_program(cache: Path, monkeypatch):
    """load_or_trace of a two-line program (no MJX: the cache's bookkeeping, not a rollout)."""
    import mujoco

    from mjxskill.engine.mjx.program_cache import load_or_trace
    from mjxskill.engine.common.worlds import Worlds

    monkeypatch.setenv("MJXSKILL_CACHE_DIR", str(cache))
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>")
    worlds = Worlds(*(jnp.full((2, 1), v, jnp.float32) for v in range(5)))
    params = jnp.arange(6, dtype=jnp.float32).reshape(2, 3)

    def body(p, w):
        return p * 2.0 + w.arm_qpos

    program = load_or_trace("tiny", model, body, params, worlds)
    return program, np.asarray(program.fn(params, worlds)), (model, body, params, worlds)


def test_a_changed_or_misplaced_program_is_detected_traced_again_and_rewritten(tmp_path, monkeypatch):
    import warnings

    from mjxskill.errors import Notice
    from mjxskill.engine.mjx.program_cache import load_or_trace

    first, expected, (model, body, params, worlds) = _tiny_program(tmp_path, monkeypatch)
    stored = tmp_path / "programs" / f"{first.key}.stablehlo"
    assert first.origin == "traced" and stored.is_file()
    with warnings.catch_warnings():
        warnings.simplefilter("error", Notice)  # an intact file is read without a word
        assert load_or_trace("tiny", model, body, params, worlds).origin == "disk"
    good = stored.read_bytes()
    changed = bytearray(good)
    changed[-20] ^= 0x01  # one bit of the program: it may still deserialize, and run wrong
    stored.write_bytes(bytes(changed))
    with pytest.warns(Notice, match=r"cannot be used \(its content does not match its digest"):
        again = load_or_trace("tiny", model, body, params, worlds)
    assert again.origin == "traced" and stored.read_bytes() == good  # rewritten
    np.testing.assert_array_equal(np.asarray(again.fn(params, worlds)), expected)
    # Another scenario's program stored under this key (a copy, a rename): never run it.
    other = load_or_trace("another scenario", model, lambda p, w: p - 1.0, params, worlds)
    stored.write_bytes((tmp_path / "programs" / f"{other.key}.stablehlo").read_bytes())
    with pytest.warns(Notice, match="it is stored for another key"):
        third = load_or_trace("tiny", model, body, params, worlds)
    assert third.origin == "traced" and stored.read_bytes() == good
    np.testing.assert_array_equal(np.asarray(third.fn(params, worlds)), expected)
    # Bytes that are no program at all (a truncated or overwritten file): the same.
    stored.write_bytes(b"not a program")
    with pytest.warns(Notice, match="cannot be used"):
        fourth = load_or_trace("tiny", model, body, params, worlds)
    assert fourth.origin == "traced" and stored.read_bytes() == good
    np.testing.assert_array_equal(np.asarray(fourth.fn(params, worlds)), expected)
