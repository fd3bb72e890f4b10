"""Throughput of stepping W worlds at once (controller + mjx.step at 500 Hz), per batching
strategy, against the native-MuJoCo Python loop (mj_jacSite + numpy impedance law + mj_step).

    python benchmarks/batching.py                      # CPU defaults
    python benchmarks/batching.py --batches 1024 4096  # e.g. on a GPU

Prints control steps per second summed over worlds (world-steps/s), compile seconds and the
ratio to the native loop measured in the same run. Compile times are cold: the persistent
compilation cache is off unless --cache is given.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

if "--cache" not in sys.argv:
    os.environ["MJXSKILL_CACHE_DIR"] = "off"

import mjxskill  # noqa: E402,F401  (XLA flags first)
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from mujoco import mjx  # noqa: E402

from mjxskill.sim import load_scene, postures  # noqa: E402
from mjxskill.engine.mjx.batching import STRATEGIES, control_step, over_worlds, put_worlds  # noqa: E402
from mjxskill.engine.mjx.controller import ControllerConfig, init_controller_state, make_command  # noqa: E402
from mjxskill.engine.native.controller import NativeControllerState, native_impedance_control  # noqa: E402
from mjxskill.sim.controller_config import N_ARM  # noqa: E402


def native_rollout(cfg, model, data, command, nullspace_target, n_steps: int):
    """Steps ``data`` in place ``n_steps`` times under a constant command (Python loop:
    controller then mj_step). Returns the final NativeControllerState."""
    mujoco.mj_forward(model, data)
    state = NativeControllerState(data.qfrc_bias[:N_ARM], np.asarray(command)[13:19], np.zeros(6))
    for _ in range(n_steps):
        tau, state = native_impedance_control(cfg, model, data, command, nullspace_target, state)
        data.ctrl[:N_ARM] = tau
        mujoco.mj_step(model, data)
    return state


def native_steps_per_second(model, cfg, qpos, command, n_steps):
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    start = time.perf_counter()
    native_rollout(cfg, model, data, command, qpos[:7], n_steps)
    return n_steps / (time.perf_counter() - start)


def make_batched_rollout(cfg, mx, n_steps, strategy, chunk):
    def one_world(data, command, nullspace_target):
        state = init_controller_state(data, command)

        def body(carry, _):
            return control_step(cfg, mx, *carry[:1], command, nullspace_target, carry[1]), None

        (data, _), _ = jax.lax.scan(body, (data, state), None, length=n_steps)
        return data

    return jax.jit(over_worlds(one_world, strategy, chunk))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="push", choices=["push", "peg", "peg_square"])
    parser.add_argument("--batches", type=int, nargs="+", default=[8, 64])
    parser.add_argument("--strategies", nargs="+", default=list(STRATEGIES), choices=STRATEGIES)
    parser.add_argument("--chunk", type=int, default=16)
    parser.add_argument("--steps", type=int, default=250, help="control steps per rollout")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cache", action="store_true", help="use the persistent compile cache")
    args = parser.parse_args(argv)

    model = load_scene(args.scene)
    cfg = ControllerConfig.from_model(model)
    qpos0 = model.key("home").qpos.copy()
    starts = postures.PUSH_STARTS if args.scene == "push" else postures.PEG_STARTS
    print(f"backend {jax.default_backend()} ({jax.devices()[0].device_kind}), scene {args.scene}, "
          f"{args.steps} control steps per rollout, XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r}")

    data = mujoco.MjData(model)
    data.qpos[:] = qpos0
    data.qpos[:7] = starts[0]
    mujoco.mj_kinematics(model, data)
    command = np.asarray(make_command(jnp.asarray(data.site("tool").xpos) + jnp.array([0.05, 0.05, 0.0]),
                                      jnp.array([0.0, 0.0, 1.0, 0.0])))
    native = max(native_steps_per_second(model, cfg, data.qpos.copy(), command, 2000) for _ in range(2))
    print(f"native MuJoCo + numpy controller (Python loop, 1 world): {native:,.0f} steps/s")

    mx = mjx.put_model(model)
    header = f"{'strategy':>8} {'W':>6} {'compile s':>10} {'world-steps/s':>14} {'x native':>9}"
    print(header)
    results = []
    for batch in args.batches:
        rng = np.random.default_rng(0)
        qpos = np.tile(data.qpos, (batch, 1))
        qpos[:, :7] = starts[rng.integers(len(starts), size=batch)]
        worlds = put_worlds(model, qpos)
        commands = jnp.tile(jnp.asarray(command, jnp.float32), (batch, 1))
        targets = jnp.asarray(qpos[:, :7], jnp.float32)
        for strategy in args.strategies:
            fn = make_batched_rollout(cfg, mx, args.steps, strategy, args.chunk)
            start = time.perf_counter()
            compiled = fn.lower(worlds, commands, targets).compile()
            compile_s = time.perf_counter() - start
            jax.block_until_ready(compiled(worlds, commands, targets))
            best = np.inf
            for _ in range(args.repeats):
                start = time.perf_counter()
                jax.block_until_ready(compiled(worlds, commands, targets))
                best = min(best, time.perf_counter() - start)
            rate = batch * args.steps / best
            results.append((strategy, batch, compile_s, rate))
            label = strategy if strategy != "chunked" else f"chunk{args.chunk}"
            print(f"{label:>8} {batch:>6} {compile_s:>10.1f} {rate:>14,.0f} {rate / native:>9.2f}", flush=True)
    return results


if __name__ == "__main__":
    main()
