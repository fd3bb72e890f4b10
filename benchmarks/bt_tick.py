"""Cost of one compiled BT tick (SkiREIL Push tree) against the reference interpreter.

    python benchmarks/bt_tick.py [--ticks 1000] [--batch 1024]

Prints, for the Push tree (8 nodes, 5 leaves) and a 20-node tree using every node kind:
* the reference interpreter (Python) per tick and machine: the baseline, measured in this run;
* one jitted ``tick`` call at batch 1 and one jitted ``vmap(tick)`` call at ``--batch`` (host
  dispatch included: what a Python loop pays per tick);
* ``tick_sequence`` (lax.scan over ticks) at batch 1 and vmapped at ``--batch``: the per-tick
  cost inside a compiled rollout, per batch and per machine;
and the compile time of each jitted function. Ratios are against the interpreter.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
import statistics
import time

import mjxskill  # noqa: F401  (XLA flags before jax runs anything)

import jax
import numpy as np

from mjxskill.bt_compiled import compile_tree, init_state, tick, tick_sequence
from mjxskill.ebt import nodes as N
from mjxskill.ebt.interpreter import Interpreter

# The example trees live with the tests that pin their semantics.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "helpers"))
from bt_examples import push_tree  # noqa: E402


def all_kinds_tree() -> N.Node:
    return N.serial_star(
        "root",
        N.selector(
            "pick",
            N.inverter(N.condition("c0")),
            N.sequence("seq", N.condition("c1"), N.timeout(N.action("a1"), 3)),
        ),
        N.parallel(
            "par",
            N.repeat(N.action("a2"), 2),
            N.retry(N.selector_star("sel_star", N.action("a3"), N.action("a4")), 2),
            N.parallel_fs("race", N.force_success(N.action("a5")), N.condition("c2")),
        ),
        N.action("a6"),
    )


def scripts(ct, batch: int, ticks: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    status = rng.choice([0, 0, 0, 1, 2], size=(batch, ticks, ct.num_leaves)).astype(np.int32)
    is_condition = ct.kind[ct.leaf_ids] == N.Kind.CONDITION
    status[..., is_condition] = rng.choice([1, 2], size=status[..., is_condition].shape)
    return status


def best_of(fn, repeats: int = 5) -> float:
    """Median wall time of ``fn()`` over ``repeats`` runs (seconds)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def bench(name: str, tree: N.Node, ticks: int, batch: int) -> None:
    ct = compile_tree(tree)
    print(f"\n{name}: {ct.num_nodes} nodes, {ct.num_leaves} leaves; {ticks} ticks, batch {batch}")
    script = scripts(ct, batch, ticks)
    leaf_ids = ct.leaf_ids.tolist()

    def interpret():
        interp = Interpreter(tree)
        for row in script[0].tolist():
            table = dict(zip(leaf_ids, row))
            interp.tick(lambda nid, node: N.Status(table[nid]))

    t_interp = best_of(interpret) / ticks
    print(f"  reference interpreter (Python)      {t_interp * 1e6:9.2f} us/tick/machine   1.00x")

    one = jax.jit(lambda state, leaf_status: tick(ct, state, leaf_status))
    start = time.perf_counter()
    jax.block_until_ready(one(init_state(ct), script[0, 0]))
    compile_one = time.perf_counter() - start

    def loop():
        state = init_state(ct)
        for t in range(ticks):
            state, root, _ = one(state, script[0, t])
        jax.block_until_ready(root)

    t_loop = best_of(loop) / ticks
    print(
        f"  jit(tick), Python loop, batch 1     {t_loop * 1e6:9.2f} us/tick           "
        f"{t_interp / t_loop:6.2f}x  (compile {compile_one:.2f} s)"
    )

    many = jax.jit(jax.vmap(lambda state, leaf_status: tick(ct, state, leaf_status)))
    states = jax.vmap(lambda _: init_state(ct))(np.arange(batch))
    start = time.perf_counter()
    jax.block_until_ready(many(states, script[:, 0]))
    compile_many = time.perf_counter() - start

    def loop_many():
        state = states
        for t in range(ticks):
            state, root, _ = many(state, script[:, t])
        jax.block_until_ready(root)

    t_many = best_of(loop_many) / ticks
    print(
        f"  jit(vmap(tick)), Python loop, batch {batch:<5} {t_many * 1e6:6.2f} us/tick  "
        f"{t_many / batch * 1e9:9.1f} ns/tick/machine"
        f"  {t_interp / (t_many / batch):9.1f}x  (compile {compile_many:.2f} s)"
    )

    seq = jax.jit(lambda state, leaf_status: tick_sequence(ct, state, leaf_status))
    batched = jax.jit(jax.vmap(lambda state, leaf_status: tick_sequence(ct, state, leaf_status)))
    for label, fn, args, machines in [
        ("tick_sequence (scan), batch 1", seq, (init_state(ct), script[0]), 1),
        (f"vmap(tick_sequence), batch {batch}", batched, (states, script), batch),
    ]:
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        compiled = time.perf_counter() - start
        per_tick = best_of(lambda: jax.block_until_ready(fn(*args))) / ticks
        per_machine = per_tick / machines
        print(
            f"  {label:<35} {per_tick * 1e6:9.2f} us/tick  {per_machine * 1e9:9.1f} ns/tick/machine"
            f"  {t_interp / per_machine:9.1f}x  (compile {compiled:.2f} s)"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=1000)
    parser.add_argument("--batch", type=int, default=1024)
    args = parser.parse_args()
    print(f"jax {jax.__version__} on {jax.devices()[0].platform} ({jax.devices()[0].device_kind})")
    bench("Push", push_tree(), args.ticks, args.batch)
    bench("all node kinds", all_kinds_tree(), args.ticks, args.batch)


if __name__ == "__main__":
    main()
