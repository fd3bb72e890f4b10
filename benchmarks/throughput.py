"""Throughput of both physics engines on the training workload, against a plain native loop, in
one run.

    python benchmarks/throughput.py                          # push, 12 s episodes, 6 sets x 7 worlds
    python benchmarks/throughput.py --task peg               # 18 s peg episodes
    python benchmarks/throughput.py --quick --json out.json  # 2 s episodes: a smoke test, not a figure
    python benchmarks/throughput.py --cache-check            # MJX's compile caches only

Measures on the same parameter sets and worlds (the operators' sets first, then random ones;
worlds from key 0), and prints as a table with the load average of each row:
* ``loop``: the plain single-process loop over native MuJoCo (``NativeRollout.run_episode``:
  the numpy controller, the reference BT interpreter and ``mj_step`` one control step at a
  time): the baseline, measured before and after everything else (ratios use the mean);
* ``native``: the native engine (episodes on MuJoCo batches with the compiled law: the
  one-process ``NativeRollout`` wrapped by ``ProcessPoolRollout`` over ``--workers`` processes,
  or alone, its batch stepped on ``--threads`` threads), the median of ``--native-calls``
  calls (default 3: this machine's rate moves by 10-25 % between single calls); with one
  process and one thread, the share of the calls spent in MuJoCo's step;
* ``mjx``: the compiled MJX rollout on 1 and on ``--devices`` host devices (a fresh process
  each: the device count is fixed when jax starts), at ``--batches`` parameter sets per call;
  compile time and XLA's buffers;
* ``bare``: ``mj_step`` alone with a constant control (the physics ceiling of one core); every
  row's ``x limit`` is its rate over cores x bare, the machine's physics limit;
* agreement: per parameter set, the success rate on MJX and on the native engine in the same
  worlds, and in how many worlds the two agree;
* memory per episode: XLA's buffers over the batch's episodes (MJX); an episode's model copy
  and MjData, arena used included (native).

The default is the real workload: the scenario's full episode length at the training batch
(6 parameter sets x 7 worlds). ``--json`` writes ``mjx_steps_per_s``, ``native_steps_per_s``,
``loop_steps_per_s``, ``best_engine``, ``best_steps_per_s``, ``best_x_loop``,
``physics_limit_steps_per_s``, ``best_share_of_limit``, ``episode_physics_steps_per_s`` (MuJoCo's
step on the episodes' own states: the one-process, one-thread call's rate over its physics share)
with ``episode_physics_share_of_limit`` (cores x that over the limit: the engine's ceiling were
its Python free), ``episode_physics_limit_steps_per_s`` (the episodes' own steps replayed in C with no Python on
every core at once, the faster of two replays, ``benchmarks/episode_physics.py``: the limit issue 48
measures an engine against), ``best_share_of_episode_physics_limit``, ``episode_physics`` (that
replay's figures, with ``paired_shares``), ``paired_share_of_episode_physics`` (the median of
``--paired-rounds`` rounds, each one call of the default engine, a worker per core, and one
all-cores replay timed in turn: both figures from the same minutes) and the rows.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if str(ROOT) not in sys.path:  # run from a checkout: this worktree's mjxskill first
    sys.path.insert(0, str(ROOT))

from mjxskill._runtime import with_host_devices  # noqa: E402  (no jax backend starts here)

HAND_FOUND_PUSH = (-0.05, -0.15, 0.07, -0.10)  # the push into the goal corner (tests/engine/mjx/test_rollout_push.py)


def _env(devices: int) -> dict:
    """Environment for an MJX worker with ``devices`` host devices (mjxskill appends its flag)."""
    env = dict(os.environ)
    env["XLA_FLAGS"] = with_host_devices(env.get("XLA_FLAGS", ""), devices)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def workload(task_name: str, seconds: float | None, sets: int, worlds: int | None):
    """(scenario, task, params (sets, P), worlds (sets, W)): identical in every process."""
    import jax
    import numpy as np

    from mjxskill import load_scenario, plan_task
    from mjxskill.engine.native.rollout import NativeRollout

    scn = load_scenario(task_name)
    task = plan_task(scn)
    rng = np.random.default_rng(0)
    params = rng.uniform(*task.bounds, size=(sets, len(task.parameter_names)))
    known = list(task.manual_parameters.values()) + ([np.array(HAND_FOUND_PUSH)] if scn.name == "push" else [])
    for i, values in enumerate(known[:sets]):  # sets known to succeed (sometimes) first
        params[i] = values
    sampler = NativeRollout(scn, task, worlds=worlds, episode_seconds=seconds)
    return scn, task, params, sampler.sample_worlds(jax.random.key(0), sets), sampler


# -- MJX, in a process of its own per device count -------------------------------------------------
def _mjx_worker(args) -> None:
    import mjxskill  # noqa: F401  (XLA flags before jax runs anything)

    import jax
    import numpy as np

    from mjxskill import compile_rollout

    batches = [int(b) for b in args.batches.split(",")]
    scn, task, params, worlds, _ = workload(args.task, args.seconds, max(batches), args.worlds)
    rollout = compile_rollout(scn, task, worlds=worlds.config_index.shape[1], episode_seconds=args.seconds)
    records = []
    for b in batches:
        p = jax.numpy.asarray(params[:b], jax.numpy.float32)
        wd = jax.tree.map(lambda x: jax.numpy.asarray(x[:b]), worlds)
        t0 = time.perf_counter()
        program = rollout.program(p, wd)
        compiled = program.fn.lower(p, wd).compile()
        compile_s = time.perf_counter() - t0
        memory = compiled.memory_analysis()
        runs = []
        for _ in range(args.reps):
            t0 = time.perf_counter()
            out = jax.block_until_ready(compiled(p, wd))
            runs.append(time.perf_counter() - t0)
        episodes = int(np.prod(wd.config_index.shape))
        xla = None if memory is None else memory.temp_size_in_bytes + memory.argument_size_in_bytes + memory.output_size_in_bytes
        records.append(dict(
            engine="mjx", devices=jax.local_device_count(), sets=b, episodes=episodes, compile_s=compile_s,
            run_s=min(runs), steps_per_s=episodes * rollout.control_steps_per_episode / min(runs),
            memory_per_episode_mb=None if xla is None else xla / episodes / 2**20, load_avg=os.getloadavg()[0],
            success=np.asarray(out.success).tolist(), objectives=np.asarray(out.objectives).tolist(),
        ))
        print(f"  [mjx, {records[-1]['devices']} device(s)] {episodes} episodes: compile {compile_s:.0f} s, "
              f"{records[-1]['steps_per_s']:.0f} steps/s", file=sys.stderr, flush=True)
    Path(args.out).write_text(json.dumps(records))


def mjx(devices: int, args) -> list[dict]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "records.json"
        cmd = [sys.executable, str(Path(__file__).resolve()), "--mjx-worker", "--task", args.task,
               "--batches", args.batches, "--reps", str(args.reps), "--out", str(out)]
        cmd += ["--seconds", str(args.seconds)] if args.seconds else []
        cmd += ["--worlds", str(args.worlds)] if args.worlds else []
        subprocess.run(cmd, env=_env(devices), check=True)
        return json.loads(out.read_text())


# -- native ------------------------------------------------------------------------------------------
def loop(engine, params, worlds) -> dict:
    """The plain single-process loop over every episode of the batch."""
    import jax
    import numpy as np

    b, w = worlds.config_index.shape
    t0 = time.perf_counter()
    for i in range(b):
        for j in range(w):
            engine.run_episode(params[i], jax.tree.map(lambda x: np.asarray(x)[i, j], worlds))
    run_s = time.perf_counter() - t0
    return dict(engine="loop", workers=1, episodes=b * w, run_s=run_s,
                steps_per_s=b * w * engine.control_steps_per_episode / run_s, load_avg=os.getloadavg()[0])


def native_engine(scn, task, params, worlds, workers: int, seconds, threads: int = 1):
    """(the one-process engine, the engine: it, or a pool of ``workers`` processes around it,
    the seconds its start took), started, its processes' first call made."""
    from mjxskill.engine.native import NativeRollout, ProcessPoolRollout

    inner = NativeRollout(scn, task, worlds=worlds.config_index.shape[1], episode_seconds=seconds)
    inner.threads = threads
    engine = ProcessPoolRollout(inner, workers) if workers > 1 else inner
    t0 = time.perf_counter()
    if isinstance(engine, ProcessPoolRollout):
        engine.start()
    # One parameter set first: each process loads the compiled law from numba's cache on its
    # first call (~0.5 s), which a training run pays once, not per batch.
    engine.run_worlds(params[:1], type(worlds)(*(x[:1] for x in worlds)))
    return inner, engine, time.perf_counter() - t0


def native(scn, task, params, worlds, workers: int, seconds, threads: int = 1, calls: int = 1) -> dict:
    """The native engine with ``workers`` processes (their start-up timed apart), or with one
    process whose batch steps on ``threads`` threads; ``calls`` timed calls, the median counts
    (``run_s``; each in ``call_s``: this machine's rate moves 10-25 % between calls). With one
    process and one thread, also the share of the time spent in MuJoCo's step
    (``physics_share``, over all the calls)."""
    import numpy as np

    inner, engine, start_s = native_engine(scn, task, params, worlds, workers, seconds, threads)
    b, w = worlds.config_index.shape
    timing = {}
    if workers == 1 and threads == 1:  # time MuJoCo's step inside the call
        inner.timing = timing
    call_s = []
    for _ in range(calls):
        t0 = time.perf_counter()
        out = engine.run_worlds(params, worlds)
        call_s.append(time.perf_counter() - t0)
    run_s = float(np.median(call_s))
    engine.close()
    return dict(engine="native", workers=workers, threads=threads, episodes=b * w, start_s=start_s, run_s=run_s,
                call_s=call_s, physics_share=timing["physics_s"] / sum(call_s) if timing else None,
                steps_per_s=b * w * engine.control_steps_per_episode / run_s,
                memory_per_episode_mb=inner.memory_per_episode() / 2**20, load_avg=os.getloadavg()[0],
                success=np.asarray(out.success).tolist(), objectives=np.asarray(out.objectives).tolist())


def bare(engine, worlds, steps: int) -> dict:
    """``mj_step`` alone in a Python loop, the arm held by a constant gravity-compensation torque."""
    import mujoco
    import numpy as np

    from mjxskill.engine.native.episode import initial_data

    world = type(worlds)(*(np.asarray(x)[0, 0] for x in worlds))
    data = initial_data(engine, engine.mj_model, world)
    data.ctrl[:7] = data.qfrc_bias[:7]
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(engine.mj_model, data)
    run_s = time.perf_counter() - t0
    return dict(engine="bare", steps=steps, run_s=run_s, steps_per_s=steps / run_s, load_avg=os.getloadavg()[0])


# -- report ----------------------------------------------------------------------------------------
def agreement(a: dict, b: dict) -> list[dict]:
    """Per parameter set: success rates on two engines in the same worlds and worlds agreeing."""
    import numpy as np

    sa, sb = np.asarray(a["success"], bool), np.asarray(b["success"], bool)
    return [dict(set=i, **{f"{a['engine']}_success_rate": float(sa[i].mean()), f"{b['engine']}_success_rate": float(sb[i].mean())},
                 worlds_agreeing=int((sa[i] == sb[i]).sum()), worlds=int(sa.shape[1])) for i in range(len(sa))]


def cache_check(args) -> dict:
    """MJX only: a second process reads the lowered program and XLA's compile from the caches."""
    with tempfile.TemporaryDirectory() as cache:
        os.environ.update(MJXSKILL_CACHE_DIR=cache, JAX_COMPILATION_CACHE_DIR=cache)
        first, second = mjx(1, args)[0], mjx(1, args)[0]
    result = dict(first_compile_s=first["compile_s"], second_compile_s=second["compile_s"],
                  ratio=second["compile_s"] / first["compile_s"])
    print(f"first process: program + compile {first['compile_s']:.1f} s; second {second['compile_s']:.2f} s "
          f"({result['ratio']:.1%})")
    return result


def main(argv=None) -> dict | None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--task", default="push", help="scenario (push, peg or a YAML path)")
    parser.add_argument("--seconds", type=float, default=None, help="episode length, s (default: the scenario's)")
    parser.add_argument("--batches", default="6", help="parameter sets per MJX call, e.g. 6,24 (the first is also "
                        "the native engine's and the loop's batch; default 6, the training batch)")
    parser.add_argument("--worlds", type=int, default=None, help="worlds per parameter set (default: the scenario's)")
    parser.add_argument("--devices", default=None, help="MJX host device counts, e.g. 1,2 (default 1,cores; 0: no MJX)")
    parser.add_argument("--workers", default=None, help="native engine worker processes, e.g. 1,2 (default 1,cores)")
    parser.add_argument("--threads", default=None, help="threads of one native process's batch, e.g. 2 (default: "
                        "cores, if more than 1)")
    parser.add_argument("--reps", type=int, default=1, help="timed MJX calls per configuration (the fastest counts)")
    parser.add_argument("--native-calls", type=int, default=3, help="timed native engine calls per configuration "
                        "(the median counts; default 3)")
    parser.add_argument("--paired-rounds", type=int, default=5, help="rounds of the default engine (a worker per "
                        "core) timed in turn with the episodes' own physics (default 5; 0: none)")
    parser.add_argument("--quick", action="store_true", help="2 s episodes (a smoke test; not the workload)")
    parser.add_argument("--cache-check", action="store_true", help="only MJX's compile-cache check")
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--mjx-worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.native_calls < 1 or args.reps < 1 or args.paired_rounds < 0:
        parser.error(f"--native-calls and --reps must be at least 1 and --paired-rounds at least 0, got "
                     f"{args.native_calls}, {args.reps} and {args.paired_rounds}")
    if args.quick and args.seconds is None:
        args.seconds = 2.0
    if args.mjx_worker:
        return _mjx_worker(args)
    if args.cache_check:
        result = cache_check(args)
        if args.json:
            args.json.write_text(json.dumps(result, indent=2))
        return result

    import mjxskill  # noqa: F401
    import jax
    import mujoco
    import numpy as np

    from mjxskill.engine.native.pool import default_workers

    cores = default_workers()
    sets = int(args.batches.split(",")[0])
    devices = sorted({int(d) for d in (args.devices or f"1,{cores}").split(",")} - {0})
    workers = sorted({int(w) for w in (args.workers or f"1,{cores}").split(",")})
    scn, task, params, worlds, engine = workload(args.task, args.seconds, sets, args.worlds)
    b, w = worlds.config_index.shape
    print(f"# throughput: {scn.name}, {b} parameter sets x {w} worlds, {engine.episode_seconds:g} s episodes "
          f"({engine.control_steps_per_episode} control steps), {cores} cores ({platform.processor() or platform.machine()}), "
          f"jax {jax.__version__}, mujoco {mujoco.__version__}, load average {os.getloadavg()[0]:.2f}", flush=True)
    rows = [loop(engine, params, worlds)]
    threads = sorted({int(t) for t in (args.threads or str(cores)).split(",")} - {0, 1})
    rows += [native(scn, task, params, worlds, n, args.seconds, calls=args.native_calls) for n in workers]
    rows += [native(scn, task, params, worlds, 1, args.seconds, threads=t, calls=args.native_calls) for t in threads]
    for d in devices:
        rows += mjx(d, args)
    rows.append(loop(engine, params, worlds))
    rows.append(bare(engine, worlds, 50000))
    from episode_physics import measure, report  # benchmarks/: the replay of these episodes' own steps

    paired = native_engine(scn, task, params, worlds, cores, args.seconds)[1] if args.paired_rounds else None
    try:  # the default engine (a worker per core) and the replay timed in turn, round by round
        call = None if paired is None else (lambda: paired.run_worlds(params, worlds))
        own = measure(engine, params, worlds, cores, call=call, steps=b * w * engine.control_steps_per_episode,
                      rounds=args.paired_rounds)
    finally:
        if paired is not None:
            paired.close()
    loops = [r for r in rows if r["engine"] == "loop"]
    loop_rate = sum(r["steps_per_s"] for r in loops) / len(loops)

    # The machine's physics limit: every core running bare mj_step (measured on one, in this run).
    limit = cores * rows[-1]["steps_per_s"]
    for r in rows:
        r["share_of_limit"] = r["steps_per_s"] / limit
    print(f"\n{'engine':<8}{'procs/dev':>10}{'threads':>8}{'episodes':>9}{'steps/s':>10}{'x loop':>8}{'x limit':>8}"
          f"{'physics':>8}{'start/compile s':>16}{'MB/episode':>11}{'load':>6}")
    for r in rows:
        procs = r.get("workers", r.get("devices", 1))
        setup = r.get("start_s", r.get("compile_s"))
        mem, physics = r.get("memory_per_episode_mb"), r.get("physics_share")
        print(f"{r['engine']:<8}{procs:>10}{r.get('threads', '-'):>8}{r.get('episodes', '-'):>9}{r['steps_per_s']:>10.0f}"
              f"{r['steps_per_s'] / loop_rate:>8.2f}{r['share_of_limit']:>8.2f}"
              f"{'-' if physics is None else f'{physics:.2f}':>8}{'-' if setup is None else f'{setup:.1f}':>16}"
              f"{'-' if mem is None else f'{mem:.2f}':>11}{r['load_avg']:>6.2f}")
    print(f"limit: {cores} cores x bare mj_step {rows[-1]['steps_per_s']:.0f} = {limit:.0f} control steps/s; "
          f"physics: the share of a one-process, one-thread call spent in MuJoCo's step")
    # MuJoCo's step on the episodes' own states (contacts: a peg in its hole collides with the
    # hole's 21 geoms) costs more than the bare step at the start state: the engine's rate with
    # no Python at all would be cores x this, its ceiling as a share of the limit.
    timed = next((r for r in rows if r["engine"] == "native" and r.get("physics_share")), None)
    episode_physics = timed["steps_per_s"] / timed["physics_share"] if timed else None
    if episode_physics:
        print(f"the episodes' own physics: {episode_physics:.0f} steps/s on one core in MuJoCo's step "
              f"({episode_physics / rows[-1]['steps_per_s']:.2f} x bare mj_step); the ceiling with no Python: "
              f"{cores * episode_physics / limit:.2f} of the limit")

    print(report(own))
    fast = [r for r in rows if r["engine"] in ("native", "mjx")]
    best = max(fast, key=lambda r: r["steps_per_s"])
    limit_own = own["all_cores_steps_per_s"]
    if limit_own:
        print(f"the best engine at {best['steps_per_s'] / limit_own:.2f} of the episodes' own physics on all cores")
    shares = own.get("paired_shares")
    paired_share = float(np.median(shares)) if shares else None
    if paired_share is not None:
        print(f"a worker per core, timed in turn with the replay over {args.paired_rounds} rounds: {paired_share:.2f} "
              f"of the episodes' own physics (rounds {min(shares):.2f}-{max(shares):.2f})")
    best_of = {e: max((r for r in fast if r["engine"] == e), key=lambda r: r["steps_per_s"], default=None)
               for e in ("mjx", "native")}
    result = dict(
        task=scn.name, episode_seconds=engine.episode_seconds, parameter_sets=b, worlds=w, cores=cores,
        loop_steps_per_s=loop_rate,
        native_steps_per_s=best_of["native"]["steps_per_s"] if best_of["native"] else None,
        mjx_steps_per_s=best_of["mjx"]["steps_per_s"] if best_of["mjx"] else None,
        best_engine=best["engine"], best_steps_per_s=best["steps_per_s"], best_x_loop=best["steps_per_s"] / loop_rate,
        bare_mj_step_steps_per_s=rows[-1]["steps_per_s"],
        physics_limit_steps_per_s=limit, best_share_of_limit=best["steps_per_s"] / limit,
        episode_physics_steps_per_s=episode_physics,
        episode_physics_share_of_limit=cores * episode_physics / limit if episode_physics else None,
        episode_physics_limit_steps_per_s=limit_own,
        best_share_of_episode_physics_limit=best["steps_per_s"] / limit_own if limit_own else None,
        paired_share_of_episode_physics=paired_share,
        episode_physics=own,
        load_avg=[r["load_avg"] for r in rows],
        rows=rows,
    )
    mjx_at_batch = next((r for r in rows if r["engine"] == "mjx" and r["sets"] == b and r["devices"] == 1), None)
    if mjx_at_batch and best_of["native"]:
        result["agreement"] = agreement(mjx_at_batch, best_of["native"])
        print("\nsuccess rate per parameter set, MJX vs native in the same worlds (worlds agreeing):")
        for a in result["agreement"]:
            print(f"  set {a['set']}: {a['mjx_success_rate']:.0%} vs {a['native_success_rate']:.0%} "
                  f"({a['worlds_agreeing']}/{a['worlds']})")
    print(f"\nbest: {best['engine']} at {best['steps_per_s']:.0f} control steps/s = {result['best_x_loop']:.2f} x the "
          f"plain loop ({loop_rate:.0f}); bare mj_step {result['bare_mj_step_steps_per_s']:.0f}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
