"""Throughput of the compiled push rollout against the native-MuJoCo baseline, in one run.

    python benchmarks/throughput.py                      # full sweep
    python benchmarks/throughput.py --quick --json out.json
    python benchmarks/throughput.py --cache-check        # compile-cache check only

Measures, and prints as a table:
* the compiled rollout (full BT + impedance controller + contacts, ``compile_rollout``) at
  several batch sizes B x W on 1 and on all host devices (``mjxskill/rollout/sharding.py``):
  control steps per second, compile time, peak memory (process RSS and XLA's buffers);
* the native-MuJoCo baseline (``mjxskill/native``: numpy controller, reference BT interpreter,
  ``mujoco.mj_step`` in a Python loop) on the same worlds and parameters, and whether it reaches
  the same success / BT outcome as the compiled rollout there;
* bare ``mj_step`` in a Python loop with a constant control (the native physics ceiling).

Episodes last 2 s by default (approach and the first second of pushing) so that a sweep fits in
half an hour on two cores; ``--seconds 12`` runs the scenario's full episodes, where MJX's
per-step cost is about twice as high in the contact-rich push phase (benchmarks/NOTES.md).

Every device count runs in a fresh subprocess (the host device count is fixed when jax starts);
the native baseline is measured before and after each of them (load on a shared machine drifts),
and ratios use the mean. ``--json`` writes the best configuration (``mjx_steps_per_s``,
``native_steps_per_s``, ``native_bare_steps_per_s``, ``compile_s``, ``batch``, ``device``) and
the whole sweep; ``--plot`` draws throughput against batch size for each backend.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if str(ROOT) not in sys.path:  # run from a checkout: this worktree's mjxskill first
    sys.path.insert(0, str(ROOT))

SCENARIO = "push"
WORLDS = 7  # W per parameter set (the scenario's n_worlds)


def _device_flag_env(devices: int) -> dict:
    """Environment for a worker with ``devices`` host devices (mjxskill appends its own flag)."""
    env = dict(os.environ)
    flags = [f for f in env.get("XLA_FLAGS", "").split() if "xla_force_host_platform_device_count" not in f]
    flags.append(f"--xla_force_host_platform_device_count={devices}")
    env["XLA_FLAGS"] = " ".join(flags)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


# --------------------------------------------------------------------------------------------
# Shared set-up: the rollout, parameters and worlds (identical in every process)
# --------------------------------------------------------------------------------------------


def _model_options(text: str | None) -> dict:
    """"iterations=2,ls_iterations=4" -> {"iterations": 2, "ls_iterations": 4} (MjOption fields)."""
    options = {}
    for item in filter(None, (text or "").split(",")):
        name, _, value = item.partition("=")
        options[name.strip()] = float(value) if "." in value else int(value)
    return options


def _setup(seconds: float, batch_sets: int, options: dict | None = None):
    """(rollout, params (batch_sets, P), worlds (batch_sets, W)); prefixes are shared across
    batch sizes, so the first episodes are the same in every configuration. ``options`` override
    fields of the model's MjOption (a lever experiment; the native baseline takes the same)."""
    import jax
    import numpy as np

    from mjxskill import compile_rollout, load_scenario
    from mjxskill.sim.model import load_model

    scn = load_scenario(SCENARIO)
    model = load_model(scn)
    for name, value in (options or {}).items():
        setattr(model.opt, name, value)
    rollout = compile_rollout(scn, worlds=WORLDS, episode_seconds=seconds, mj_model=model)
    rng = np.random.default_rng(0)
    lo, hi = rollout.bounds  # (2, P)
    params = rng.uniform(lo, hi, size=(batch_sets, len(lo))).astype(np.float32)
    manual = list(rollout.task.manual_parameters.values())  # (P,) each, in parameter_names order
    for i, values in enumerate(manual[:batch_sets]):  # operators' settings first: some succeed
        params[i] = values
    worlds = rollout.sample_worlds(jax.random.key(0), batch_sets)
    return rollout, params, worlds


# --------------------------------------------------------------------------------------------
# Worker: the compiled rollout at each batch size, in a process with a fixed device count
# --------------------------------------------------------------------------------------------


def _worker(args) -> None:
    import mjxskill  # noqa: F401  (XLA flags before jax runs anything)

    import jax
    import jax.monitoring
    import numpy as np

    hits = []
    jax.monitoring.register_event_listener(
        lambda event, **kw: hits.append(event) if event == "/jax/compilation_cache/cache_hits" else None
    )
    sets = [int(b) for b in args.batches.split(",")]
    rollout, params, worlds = _setup(args.seconds, max(sets), _model_options(args.options))
    steps = rollout.control_steps_per_episode
    records = []
    for b in sets:
        p = jax.numpy.asarray(params[:b])
        wd = jax.tree.map(lambda x: x[:b], worlds)
        n_hits = len(hits)
        # Getting the lowered program (traced, or read from the program cache on one device)
        # and XLA's compile (what the persistent compilation cache saves) are timed apart;
        # their sum is what a first call pays.
        t0 = time.perf_counter()
        program = rollout.program(p, wd)
        lowered = program.fn.lower(p, wd)
        lower_s = time.perf_counter() - t0
        compiled = lowered.compile()
        xla_compile_s = time.perf_counter() - t0 - lower_s
        compile_s = lower_s + xla_compile_s
        memory = compiled.memory_analysis()
        runs = []
        for _ in range(args.reps):
            t0 = time.perf_counter()
            out = jax.block_until_ready(compiled(p, wd))
            runs.append(time.perf_counter() - t0)
        run_s = min(runs)
        records.append(
            dict(
                backend="mjx",
                devices=jax.local_device_count(),
                device=str(jax.devices()[0].device_kind),
                params=b,
                worlds=WORLDS,
                batch=b * WORLDS,
                seconds=args.seconds,
                options=args.options or "",
                compile_s=compile_s,
                trace_lower_s=lower_s,
                program_origin=program.origin,
                xla_compile_s=xla_compile_s,
                cache_hit=len(hits) > n_hits,
                run_s=run_s,
                run_all_s=runs,
                steps_per_s=b * WORLDS * steps / run_s,
                peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                xla_buffers_mb=None
                if memory is None
                else (memory.temp_size_in_bytes + memory.argument_size_in_bytes + memory.output_size_in_bytes) / 2**20,
                objectives=np.asarray(out.objectives).tolist(),
                success=np.asarray(out.success).tolist(),
                bt_status=np.asarray(out.metrics["bt_status"]).tolist(),
                load_avg=os.getloadavg()[0],
            )
        )
        print(f"  [worker d={records[-1]['devices']}] batch {b * WORLDS}: compile {compile_s:.1f} s, "
              f"{records[-1]['steps_per_s']:.0f} steps/s", file=sys.stderr, flush=True)
    Path(args.out).write_text(json.dumps(records))


def _run_worker(devices: int, batches: list[int], seconds: float, reps: int, extra_env=None, options=None) -> list[dict]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "records.json"
        cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", "--batches", ",".join(map(str, batches)),
               "--seconds", str(seconds), "--reps", str(reps), "--out", str(out)]
        if options:
            cmd += ["--options", options]
        env = _device_flag_env(devices)
        env.update(extra_env or {})
        subprocess.run(cmd, env=env, check=True)
        return json.loads(out.read_text())


# --------------------------------------------------------------------------------------------
# Native baseline (in the parent process)
# --------------------------------------------------------------------------------------------


def _native(rollout, params, worlds, episodes: int, options: dict | None = None) -> dict:
    """Native steps/s over the first ``episodes`` episodes (param set-major), and their outcomes."""
    import jax
    import numpy as np

    from mjxskill.native import NativeRollout

    native = NativeRollout(rollout.scenario, rollout.task, worlds=rollout.worlds,
                           episode_seconds=rollout.episode_seconds, mj_model=rollout.mj_model)
    worlds = jax.tree.map(np.asarray, worlds)
    n_sets = -(-episodes // WORLDS)
    t0 = time.perf_counter()
    done, outcomes = 0, []
    for i in range(n_sets):
        for j in range(WORLDS):
            if done == episodes:
                break
            res = native.run_episode(params[i], jax.tree.map(lambda x: x[i, j], worlds))
            outcomes.append((bool(res.success), int(res.bt_status)))
            done += 1
    elapsed = time.perf_counter() - t0
    return dict(backend="native", episodes=done, run_s=elapsed,
                steps_per_s=done * native.control_steps_per_episode / elapsed, outcomes=outcomes,
                load_avg=os.getloadavg()[0])


def _native_bare(rollout, worlds, steps: int, options: dict | None = None) -> dict:
    """Bare mj_step in a Python loop, the arm held by a constant gravity-compensation torque."""
    import mujoco
    import numpy as np

    from mjxskill.native import NativeRollout

    native = NativeRollout(rollout.scenario, rollout.task, worlds=rollout.worlds,
                           episode_seconds=rollout.episode_seconds, mj_model=rollout.mj_model)
    world = __import__("jax").tree.map(lambda x: np.asarray(x)[0, 0], worlds)
    model = native.model
    data = native._initial_data(world)
    data.ctrl[:7] = data.qfrc_bias[:7]
    mujoco.mj_step(model, data)
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data)
    elapsed = time.perf_counter() - t0
    return dict(backend="native_bare", steps=steps, run_s=elapsed, steps_per_s=steps / elapsed)


# --------------------------------------------------------------------------------------------
# Compile-cache check: two fresh processes, one temporary cache
# --------------------------------------------------------------------------------------------


def cache_check(seconds: float) -> dict:
    with tempfile.TemporaryDirectory() as cache:
        env = {"MJXSKILL_CACHE_DIR": cache, "JAX_COMPILATION_CACHE_DIR": cache}
        first = _run_worker(1, [1], seconds, 1, env)[0]
        files = len(os.listdir(cache))
        second = _run_worker(1, [1], seconds, 1, env)[0]
    result = dict(first_compile_s=first["compile_s"], second_compile_s=second["compile_s"],
                  ratio=second["compile_s"] / first["compile_s"],
                  first_xla_compile_s=first["xla_compile_s"], second_xla_compile_s=second["xla_compile_s"],
                  xla_ratio=second["xla_compile_s"] / first["xla_compile_s"],
                  first_trace_lower_s=first["trace_lower_s"], second_trace_lower_s=second["trace_lower_s"],
                  first_program=first["program_origin"], second_program=second["program_origin"],
                  cache_files=files, first_cache_hit=first["cache_hit"], second_cache_hit=second["cache_hit"])
    print(f"compile cache, first process: program {first['program_origin']} in {first['trace_lower_s']:.1f} s + XLA compile "
          f"{first['xla_compile_s']:.1f} s (cache hit: {first['cache_hit']})")
    print(f"compile cache, second process: program {second['program_origin']} in {second['trace_lower_s']:.2f} s + XLA compile "
          f"{second['xla_compile_s']:.2f} s (cache hit: {second['cache_hit']})")
    print(f"XLA compile ratio {result['xla_ratio']:.3f}; first-call ratio (tracing included) {result['ratio']:.3f}; "
          f"{files} cache files")
    return result


# --------------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------------


def _same_outputs(a: dict, b: dict) -> float:
    """Max |difference| of objectives between two records of the same batch (inf: outcomes differ)."""
    import numpy as np

    if a["success"] != b["success"] or a["bt_status"] != b["bt_status"]:
        return float("inf")
    return float(np.max(np.abs(np.asarray(a["objectives"]) - np.asarray(b["objectives"]))))


def plot(sweep: list[dict], native: float, bare: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for d in sorted({r["devices"] for r in sweep}):
        rows = sorted((r for r in sweep if r["devices"] == d), key=lambda r: r["batch"])
        ax.plot([r["batch"] for r in rows], [r["steps_per_s"] for r in rows], "o-",
                label=f"MJX compiled rollout, {d} host device{'s' * (d > 1)}")
    ax.axhline(native, color="k", ls="--", label="native MuJoCo + numpy controller + BT (1 process)")
    ax.axhline(bare, color="gray", ls=":", label="bare mj_step loop (no control)")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("batch B x W (episodes per call)")
    ax.set_ylabel("control steps / s")
    ax.set_title(f"push rollout throughput ({platform.processor() or platform.machine()}, {os.cpu_count()} cores)")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None) -> dict | None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="two batch sizes, short episodes")
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--plot", type=Path, default=HERE / "throughput.png", help="scaling figure (PNG)")
    parser.add_argument("--cache-check", action="store_true", help="only the compile-cache check")
    parser.add_argument("--devices", default=None, help="host device counts to sweep, e.g. 1,2 (default 1,cpu_count)")
    parser.add_argument("--batches", default=None, help="parameter sets per call (x W=7 episodes), e.g. 1,4,8")
    parser.add_argument("--seconds", type=float, default=None, help="episode length, s")
    parser.add_argument("--reps", type=int, default=2, help="timed calls per configuration (the fastest counts)")
    parser.add_argument("--native-episodes", type=int, default=None)
    parser.add_argument("--options", default=None,
                        help="MjOption overrides for a lever experiment, e.g. iterations=2,ls_iterations=4 "
                             "(applied to the compiled rollout and the native baseline alike)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        return _worker(args)

    seconds = args.seconds or 2.0
    if args.cache_check:
        result = dict(cache_check=cache_check(seconds))
        if args.json:
            args.json.write_text(json.dumps(result, indent=2))
        return result

    import mjxskill  # noqa: F401
    import jax
    import mujoco

    batches = [int(b) for b in (args.batches or ("1,4" if args.quick else "1,2,4,8,16")).split(",")]
    devices = [int(d) for d in (args.devices or f"1,{os.cpu_count()}").split(",")]
    devices = sorted(set(devices))
    native_episodes = args.native_episodes or (WORLDS if args.quick else 2 * WORLDS)
    options = _model_options(args.options)
    rollout, params, worlds = _setup(seconds, max(batches), options)
    print(f"# throughput: {SCENARIO}, W={WORLDS}, {seconds:g} s episodes "
          f"({rollout.control_steps_per_episode} control steps), {os.cpu_count()} cores, "
          f"jax {jax.__version__}, mujoco {mujoco.__version__}, load average {os.getloadavg()[0]:.1f}", flush=True)

    natives, sweep = [_native(rollout, params, worlds, native_episodes, options)], []
    for d in devices:
        sweep += _run_worker(d, batches, seconds, args.reps, options=args.options)
        natives.append(_native(rollout, params, worlds, native_episodes, options))
    bare = _native_bare(rollout, worlds, 20000 if args.quick else 50000, options)
    native_rate = sum(n["steps_per_s"] for n in natives) / len(natives)

    # Outcome agreement: native vs MJX (first episodes), and every device count vs 1 device.
    first = max(sweep, key=lambda r: (r["batch"], -r["devices"]))  # most episodes, fewest devices
    mjx_outcomes = [(s, st) for s_row, st_row in zip(first["success"], first["bt_status"]) for s, st in zip(s_row, st_row)]
    native_outcomes = [tuple(o) for o in natives[0]["outcomes"]]
    agree = sum(a == b for a, b in zip(native_outcomes, mjx_outcomes))
    agree_success = sum(a[0] == b[0] for a, b in zip(native_outcomes, mjx_outcomes))
    agree_status = sum(a[1] == b[1] for a, b in zip(native_outcomes, mjx_outcomes))
    for r in sweep:
        base = next(x for x in sweep if x["batch"] == r["batch"] and x["devices"] == min(devices))
        r["max_objective_diff_vs_1_device"] = _same_outputs(r, base)
        # XLA's CPU code (and its float32 rounding) depends on the batch size, so the exact
        # check is against one device running the batch one shard holds: the first shard's
        # parameter sets must come out bit for bit the same.
        shard = -(-r["batch"] // r["devices"])
        same_shard = [x for x in sweep if x["devices"] == 1 and x["batch"] == shard]
        r["first_shard_bitwise_equal_to_1_device"] = None
        if r["devices"] > 1 and same_shard and shard % WORLDS == 0:
            n = shard // WORLDS
            r["first_shard_bitwise_equal_to_1_device"] = (
                r["objectives"][:n] == same_shard[0]["objectives"][:n] and r["success"][:n] == same_shard[0]["success"][:n]
            )

    print(f"\n{'backend':<10}{'devices':>8}{'batch':>7}{'steps/s':>11}{'x native':>10}{'compile s':>11}"
          f"{'peak RSS MB':>13}{'XLA MB':>8}{'load':>6}  vs 1 device: max |objective diff| (outcomes), shard bitwise")
    for r in sweep:
        xla = "-" if r["xla_buffers_mb"] is None else f"{r['xla_buffers_mb']:.2f}"
        diff = r["max_objective_diff_vs_1_device"]
        same = "same" if diff != float("inf") else "DIFFERENT"
        bitwise = {None: "-", True: "equal", False: "NOT equal"}[r["first_shard_bitwise_equal_to_1_device"]]
        print(f"{'mjx':<10}{r['devices']:>8}{r['batch']:>7}{r['steps_per_s']:>11.0f}{r['steps_per_s'] / native_rate:>10.2f}"
              f"{r['compile_s']:>11.1f}{r['peak_rss_mb']:>13.0f}{xla:>8}{r['load_avg']:>6.1f}"
              f"  {diff:.2g} ({same}), {bitwise}")
    for i, n in enumerate(natives):
        print(f"{'native':<10}{1:>8}{1:>7}{n['steps_per_s']:>11.0f}{n['steps_per_s'] / native_rate:>10.2f}"
              f"{'-':>11}{'-':>13}{'-':>8}{n['load_avg']:>6.1f}  (run {i + 1} of {len(natives)}, {n['episodes']} episodes)")
    print(f"{'bare':<10}{1:>8}{1:>7}{bare['steps_per_s']:>11.0f}{bare['steps_per_s'] / native_rate:>10.2f}")
    n = len(native_outcomes)
    print(f"\nnative vs MJX on the first {n} episodes: success equal in {agree_success}/{n}, "
          f"BT status equal in {agree_status}/{n}, both in {agree}/{n}")

    best = max(sweep, key=lambda r: r["steps_per_s"])
    result = dict(
        mjx_steps_per_s=best["steps_per_s"],
        native_steps_per_s=native_rate,
        native_bare_steps_per_s=bare["steps_per_s"],
        ratio_mjx_to_native=best["steps_per_s"] / native_rate,
        compile_s=best["compile_s"],
        batch=best["batch"],
        device=f"{best['device']} x {best['devices']} host devices",
        devices=best["devices"],
        episode_seconds=seconds,
        model_options=options,
        cpu_count=os.cpu_count(),
        load_avg_start_end=[natives[0]["load_avg"], natives[-1]["load_avg"]],
        outcome_agreement=dict(success=agree_success, bt_status=agree_status, both=agree, episodes=len(native_outcomes)),
        sweep=sweep,
        native_runs=natives,
        native_bare=bare,
    )
    print(f"best: {best['steps_per_s']:.0f} steps/s at batch {best['batch']} on {best['devices']} device(s) = "
          f"{result['ratio_mjx_to_native']:.2f} x native ({native_rate:.0f}); bare mj_step {bare['steps_per_s']:.0f}")
    if args.plot:
        plot(sweep, native_rate, bare["steps_per_s"], args.plot)
        print(f"figure: {args.plot}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
