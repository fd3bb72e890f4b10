"""The native engine against its plain loop, and its worker processes against one process:
the same episodes, the same numbers.

The plain loop (``mjxskill.engine.native_reference.run_plain``: every episode in
``NativeRollout.run_episode``, one control step at a time, the scalar numpy controller) is the
reference. The engine's own stepping (``mjxskill.engine.native.batched``: MuJoCo batches and the
compiled law) evaluates the same law in a different order of floating-point operations, so the
two may differ in the last bits. The worker processes of ``ProcessPoolRollout`` run the engine
on slices of the episodes (2 and 4 workers), which never interact: bit-identical.
"""

import json

import jax
import numpy as np
import pytest

from mjxskill import load_scenario, plan_task
from mjxskill.engine.build import ENGINES, build_rollout, resolve_engine
from mjxskill.engine.native import NativeRollout, ProcessPoolRollout
from mjxskill.engine.native_reference import run_plain
from scenario_texts import shipped_text

HAND_FOUND = [-0.05, -0.15, 0.07, -0.10]  # the push into the goal corner (tests/engine/mjx/test_rollout_push.py)


def assert_same_outputs(a, b, atol=0.0):
    assert set(a.metrics) == set(b.metrics)
    for name in a.metrics:
        x, y = np.asarray(a.metrics[name], float), np.asarray(b.metrics[name], float)
        np.testing.assert_allclose(x, y, rtol=0, atol=atol, err_msg=name)
    np.testing.assert_allclose(np.asarray(a.objectives), np.asarray(b.objectives), rtol=0, atol=atol)
    np.testing.assert_array_equal(a.success, b.success)


@pytest.fixture(scope="module")
def push():
    scn = load_scenario("push")
    task = plan_task(scn)
    rng = np.random.default_rng(0)
    params = np.concatenate([[HAND_FOUND], rng.uniform(*task.bounds, size=(2, 4))])
    return scn, task, params


def test_the_engine_equals_the_plain_loop_on_the_push(push):
    scn, task, params = push
    engine = NativeRollout(scn, task, worlds=2, episode_seconds=3.0)
    worlds = engine.sample_worlds(jax.random.key(2), len(params))
    plain = run_plain(engine, params, worlds)
    batched = engine.run_worlds(params, worlds)
    assert_same_outputs(plain, batched, atol=1e-9)
    for name in ("bt_status", "bt_done_tick", "diverged", "config_index"):
        np.testing.assert_array_equal(plain.metrics[name], batched.metrics[name])


def test_the_engine_equals_the_plain_loop_with_the_search_spiral():
    # The peg's spiral overlay is the part of the references computed step by step. On the
    # square peg: the round one's mesh-box contacts amplify the vectorized controller's last-bit
    # differences (one reward total of 34 differed by 0.01 after 4 s, the others agreed to 1e-9).
    scn = load_scenario("peg_square")
    task = plan_task(scn)
    params = np.array([[-6.0, 0.01, 0.05], [-9.0, 0.05, 0.2]])
    engine = NativeRollout(scn, task, worlds=2, episode_seconds=4.0)
    worlds = engine.sample_worlds(jax.random.key(1), len(params))
    assert_same_outputs(run_plain(engine, params, worlds), engine.run_worlds(params, worlds), atol=1e-9)


def test_worker_processes_give_one_process_results_bit_for_bit(push):
    scn, task, params = push
    one = NativeRollout(scn, task, worlds=3, episode_seconds=1.0)
    key = jax.random.key(7)
    with ProcessPoolRollout(NativeRollout(scn, task, worlds=3, episode_seconds=1.0), workers=4) as four:
        assert_same_outputs(one(params, key), four(params, key))  # 9 episodes round-robin over 4 workers
    with ProcessPoolRollout(NativeRollout(scn, task, worlds=3, episode_seconds=1.0), workers=2) as two:
        assert_same_outputs(one(params, key), two(params, key))
        # an episode's result does not depend on which episodes share its call
        worlds = one.sample_worlds(key, len(params))
        alone = two.run_worlds(params[1:2], jax.tree.map(lambda x: x[1:2], worlds))
        together = one.run_worlds(params, worlds)
        for name in ("reward_object_position", "reward_reference_tracking", "position_error"):
            np.testing.assert_array_equal(np.asarray(alone.metrics[name])[0], np.asarray(together.metrics[name])[1])


def test_an_engine_dropped_without_close_stops_its_workers(push):
    import gc

    scn, task, _ = push
    engine = ProcessPoolRollout(NativeRollout(scn, task, worlds=1, episode_seconds=0.2), workers=2)
    pool = engine.start()
    procs = list(pool.procs)
    assert all(p.poll() is None for p in procs)
    del engine, pool
    gc.collect()
    assert all(p.returncode is not None for p in procs)  # killed and reaped, no zombie left


def test_a_worker_that_cannot_start_says_why(tmp_path, push):
    scn, task, params = push
    copy = tmp_path / "push.yaml"
    copy.write_text(shipped_text("push"))
    moved = load_scenario(copy)
    engine = ProcessPoolRollout(NativeRollout(moved, plan_task(moved), worlds=1, episode_seconds=0.2), workers=2)
    copy.write_text(copy.read_text() + "\n# edited after the engine was built\n")
    with pytest.raises(RuntimeError, match="changed since the engine was built"):
        engine(params[:2], jax.random.key(0))
    engine.close()


def test_both_engines_draw_the_same_worlds_for_a_key(push):
    scn, task, _ = push
    native = build_rollout(scn, task, "native", worlds=3, episode_seconds=0.5, workers=1)
    compiled = build_rollout(scn, task, "mjx", worlds=3, episode_seconds=0.5)
    a, b = native.sample_worlds(jax.random.key(4), 2), compiled.sample_worlds(jax.random.key(4), 2)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert native.parameter_names == compiled.parameter_names
    np.testing.assert_array_equal(native.bounds, compiled.bounds)


def test_auto_picks_mjx_on_accelerators_and_native_on_a_cpu():
    assert resolve_engine("auto", "gpu")[0] == "mjx" and resolve_engine("auto", "tpu")[0] == "mjx"
    assert resolve_engine("auto", "cpu")[0] == "native"
    assert [resolve_engine(e)[0] for e in ENGINES] == list(ENGINES)
    with pytest.raises(ValueError, match="unknown engine 'warp'"):
        resolve_engine("warp")


def test_bad_params_are_refused_as_by_the_compiled_rollout(push):
    scn, task, _ = push
    engine = NativeRollout(scn, task, worlds=1, episode_seconds=0.2)
    with pytest.raises(ValueError, match=r"shape \(B, 4\)"):
        engine(np.zeros((2, 3)), jax.random.key(0))
    with pytest.raises(ValueError, match="finite"):
        engine(np.full((1, 4), np.nan), jax.random.key(0))
    json.dumps(engine.task.goal)  # plain data: what the worker recipe sends


def test_a_diverging_world_is_contained_by_the_engine_as_in_the_loop():
    # A NaN start posture diverges at the first tick; its companions in the same call are
    # untouched and it is charged the worst rewards, as the plain loop and MJX do.
    scn = load_scenario("peg")
    task = plan_task(scn)
    params = np.array([[-6.0, 0.01, 0.05]] * 2)
    engine = NativeRollout(scn, task, worlds=2, episode_seconds=0.5)
    worlds = engine.sample_worlds(jax.random.key(3), 2)
    broken = worlds._replace(arm_qpos=worlds.arm_qpos.copy())
    broken.arm_qpos[1, 0] = np.nan
    plain, batched, clean = (run_plain(engine, params, broken), engine.run_worlds(params, broken),
                             engine.run_worlds(params, worlds))
    assert bool(batched.metrics["diverged"][1, 0]) and int(np.sum(batched.metrics["diverged"])) == 1
    assert not bool(batched.success[1, 0])
    for term in engine.terms:
        assert float(batched.metrics[f"reward_{term.name}"][1, 0]) == pytest.approx(term.worst_raw * engine.setup.ticks)
    assert_same_outputs(plain, batched, atol=1e-9)
    for name in batched.metrics:  # the other episodes of the call: as without the broken one
        np.testing.assert_array_equal(np.asarray(batched.metrics[name])[0], np.asarray(clean.metrics[name])[0])
        np.testing.assert_array_equal(np.asarray(batched.metrics[name])[1, 1], np.asarray(clean.metrics[name])[1, 1])
