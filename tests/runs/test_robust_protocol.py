"""The robust protocol (mjxskill.runs.training_protocol): the success bound against scipy's Beta,
pooling against the pooled values themselves, the pooled CSV, replication in the training loop,
the race, and runs killed with SIGKILL during replication and during the race that resume to
the uninterrupted result."""

import json
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from mjxskill.engine.common.types import RolloutOutput
from mjxskill.errors import RunError
from mjxskill.evaluation import racing
from mjxskill.runs.run_dir import EVALUATIONS, Evaluations, Run, read_csv
from mjxskill.runs.training_protocol import (MAX_WORLDS_FACTOR, SUCCESS_OBJECTIVE, objective_names, pooled_moments,
                                             success_lower_bound, success_upper_bound)
from mjxskill.training import replication
from mjxskill.training.front import pareto_mask_of
from mjxskill.training.loop import BatchResult, train
from cli_helpers import HELPERS
from toy_runs import make_config

QUICK_GP = dict(n_raw=64, n_restarts=2, n_opt_steps=10, fit_starts=1, fit_steps=10)
WORLDS = 7
CONFIG = make_config(budget=40, batch_size=4, n_init=8, seed=2, worlds=WORLDS, optimizer_options=QUICK_GP,
                     protocol="robust", objective_names=("reach", "force", SUCCESS_OBJECTIVE))


def toy_objective(x: np.ndarray, iteration: int) -> BatchResult:
    """Per-world outcomes of a closed-form task: the success probability peaks at x0 = 0.6, the
    reach objective is noisy; the worlds depend on the batch index as the real rollout's do (and
    here on the row's parameters, so that a row rolled out alone gets what it got in its batch)."""
    rngs = [np.random.default_rng([iteration, *np.round((row + 1) * 1e9).astype(np.int64)]) for row in x]
    draws = np.array([rng.random((2, WORLDS)) for rng in rngs])  # (n, 2, W)
    p = np.clip(1 - (x[:, 0] - 0.6) ** 2 * 4, 0, 1)
    success = draws[:, 0] < p[:, None]
    reach = -(x[:, 0, None] - 0.3) ** 2 + 0.05 * (draws[:, 1] - 0.5)
    force = np.broadcast_to(-np.abs(x[:, 1, None]) - x[:, 0, None], reach.shape)
    per_world = np.stack([reach, force], axis=2)
    return BatchResult(per_world.mean(axis=1), success.mean(axis=1), 10 * x[:, 0], 3 * x[:, 0], 7 + 0 * x[:, 0],
                       spread=per_world.std(axis=1, ddof=1), worlds=WORLDS)


def new_run(tmp_path, name, config=CONFIG) -> Run:
    src = tmp_path / "src.yaml"
    src.write_text("name: toy\n")
    run = Run(tmp_path / name)
    run.create(config, str(src), {})
    return run


# -- the success bound --------------------------------------------------------------------------

@settings(max_examples=60, deadline=None)
@given(st.integers(1, 500), st.floats(0, 1), st.sampled_from([0.025, 0.05, 0.1]))
def test_the_success_bound_is_the_quantile_of_scipys_beta_posterior(n, share, q):
    s = round(share * n)
    expected = stats.beta(s + 0.5, n - s + 0.5).ppf(q)
    assert success_lower_bound(s, n, q) == pytest.approx(expected, rel=1e-10, abs=1e-12)
    assert success_upper_bound(s, n, q) == pytest.approx(stats.beta(s + 0.5, n - s + 0.5).ppf(1 - q), rel=1e-10)


def test_more_worlds_of_the_same_rate_raise_the_bound_and_7_of_7_ranks_below_28_of_28():
    bounds = success_lower_bound(np.array([7, 14, 28, 56]), np.array([7, 14, 28, 56]))
    assert np.all(np.diff(bounds) > 0)
    assert success_lower_bound(7, 7) < success_lower_bound(27, 28)


@pytest.mark.parametrize("n, p", [(28, 0.5), (28, 0.8), (100, 0.8), (100, 0.9), (100, 0.95)])
def test_the_bound_lies_above_the_true_rate_about_as_often_as_its_quantile(n, p):
    # Jeffreys' interval: its one-sided error is close to nominal away from the edge (Brown, Cai,
    # DasGupta 2001); exact, from the binomial distribution of the successes
    s = np.arange(n + 1)
    error = stats.binom.pmf(s, n, p)[success_lower_bound(s, n) > p].sum()
    assert error == pytest.approx(0.05, abs=0.015)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=20), st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=20))
def test_pooled_moments_equal_the_moments_of_the_joined_values(a, b):
    a, b = np.array(a), np.array(b)
    sd = lambda v: v.std(ddof=1) if len(v) > 1 else np.nan  # noqa: E731
    n, mean, spread = pooled_moments(len(a), a.mean(), sd(a), len(b), b.mean(), sd(b))
    joined = np.concatenate([a, b])
    assert n == len(joined)
    assert mean == pytest.approx(joined.mean(), abs=1e-9 * (1 + np.abs(joined).max()))
    assert spread == pytest.approx(joined.std(ddof=1), abs=1e-7 * (1 + np.abs(joined).max()))


def test_a_scenario_objective_named_as_the_success_bound_is_refused_by_the_robust_protocol():
    from mjxskill.errors import ScenarioError

    with pytest.raises(ScenarioError, match=f"objective '{SUCCESS_OBJECTIVE}' has the name of the objective the robust"):
        objective_names(("a", SUCCESS_OBJECTIVE), "robust")
    assert objective_names(("a", SUCCESS_OBJECTIVE), "paper") == ("a", SUCCESS_OBJECTIVE)
    assert objective_names(("a", "b"), "robust") == ("a", "b", SUCCESS_OBJECTIVE)


# -- the loop ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("robust")
    run = new_run(tmp, "full")
    return run, train(run, CONFIG, toy_objective)


def test_replications_pool_every_world_of_their_parameter_set(trained):
    run, ev = trained
    assert ev.pooled and len(ev) == CONFIG.training_rows == 30  # 3/4 of the budget: the race has the rest
    again = np.flatnonzero(ev.replaces >= 0)
    n_batches_after_warmup = len(set(ev.iteration[ev.iteration >= 2]))
    assert len(again) == n_batches_after_warmup  # one place of every batch after the warm-up
    replication.check_pointers(ev, "test")
    for i in again:
        r = ev.replaces[i]
        np.testing.assert_array_equal(ev.params[i], ev.params[r])
        assert ev.worlds[i] == ev.worlds[r] + WORLDS <= MAX_WORLDS_FACTOR * WORLDS
    # the pooled values are the pooled worlds': rebuild every replicated set from its chain of rows
    for i in again:
        chain = [i]
        while ev.replaces[chain[-1]] >= 0:
            chain.append(ev.replaces[chain[-1]])
        first = chain[-1]
        results = [toy_objective(ev.params[[k]], int(ev.iteration[k])) for k in reversed(chain)]
        rate = np.mean([r.success_rate[0] for r in results])
        assert ev.success_rate[i] == pytest.approx(rate)
        assert ev.objectives[i, 0] == pytest.approx(np.mean([r.objectives[0, 0] for r in results]))
        assert ev.objectives[i, -1] == pytest.approx(success_lower_bound(rate * ev.worlds[i], ev.worlds[i]))
        assert ev.worlds[first] == WORLDS


def test_the_front_and_the_hypervolume_count_each_parameter_set_once(trained):
    run, ev = trained
    front = run.pareto(CONFIG)
    current = ev.current()
    assert current.sum() == len(ev) - np.sum(ev.replaces >= 0)
    assert not np.any(pareto_mask_of(ev) & ~current)
    assert len({tuple(p) for p in front.params}) == len(front)


def test_the_pooled_csv_round_trips_exactly(trained):
    run, ev = trained
    back = read_csv(run.path / EVALUATIONS, CONFIG.columns(), CONFIG.bounds)
    for a, b in zip(ev, back):
        np.testing.assert_array_equal(a, b)
    assert CONFIG.columns()[-5:] == ["worlds", "replaces", "sd_reach", "sd_force", f"sd_{SUCCESS_OBJECTIVE}"]


def test_a_replaces_pointer_to_another_parameter_set_is_refused(trained, tmp_path):
    run, ev = trained
    i = int(np.flatnonzero(ev.replaces >= 0)[0])
    bad = Evaluations(*ev[:8], replaces=np.where(np.arange(len(ev)) == i, 0, ev.replaces), spread=ev.spread)
    with pytest.raises(RunError, match=f"row {i} .* replaces row 0"):
        replication.check_pointers(bad, "evaluations.csv")


def test_the_model_sees_the_success_rate_with_less_noise_where_more_worlds_pooled(trained):
    _, ev = trained
    x, values, noise = replication.model_view(ev)
    current = ev.take(ev.current())
    np.testing.assert_array_equal(values[:, -1], current.success_rate)
    same_rate = current.success_rate == 1.0
    if same_rate.sum() > 1 and len(set(current.worlds[same_rate])) > 1:
        order = np.argsort(current.worlds[same_rate])
        assert np.all(np.diff(noise[same_rate, -1][order]) <= 1e-15)


# -- SIGKILL during replication and during the race ------------------------------------------

KILLED_TRAINING = textwrap.dedent("""
    import os, signal, sys
    sys.path[:0] = [{tests!r}, {helpers!r}]
    from test_robust_protocol import CONFIG, toy_objective
    from mjxskill.runs.run_dir import Run
    from mjxskill.training.loop import train
    kill_at = int(sys.argv[2])
    def evaluate(x, iteration):
        if iteration == kill_at:
            os.kill(os.getpid(), signal.SIGKILL)
        return toy_objective(x, iteration)
    train(Run(sys.argv[1]), CONFIG, evaluate)
""")


def test_a_run_killed_during_replication_resumes_to_the_same_rows(trained, tmp_path):
    run, _ = trained
    cut = new_run(tmp_path, "cut")
    script = tmp_path / "kill.py"
    script.write_text(KILLED_TRAINING.format(tests=os.path.dirname(__file__), helpers=str(HELPERS)))
    done = subprocess.run([sys.executable, str(script), str(cut.path), "5"], capture_output=True, text=True, timeout=900)
    assert done.returncode == -signal.SIGKILL, done.stderr[-2000:]
    rows = read_csv(cut.path / EVALUATIONS, CONFIG.columns())
    assert 0 < np.sum(rows.replaces >= 0) and set(rows.iteration) == set(range(5))  # killed after replicating
    train(cut, CONFIG, toy_objective)
    assert (cut.path / EVALUATIONS).read_text() == (run.path / EVALUATIONS).read_text()


class FakeRollout:
    """What the race needs of a rollout: per-configuration worlds and per-world success that depends
    on the parameters and the world only (a deterministic hash of both)."""

    class scenario:  # noqa: N801  (the attribute a rollout has)
        bt_hz = 10

        class robot:  # noqa: N801
            start_configs = np.zeros((3, 7))

    def __init__(self, kill_at_call=None):
        self.calls, self.kill_at_call = 0, kill_at_call

    def worlds_per_config(self, key, per_config, configs):
        import jax

        draws = np.asarray(jax.random.uniform(key, (len(configs) * per_config,)))
        return draws

    def run_worlds(self, params, worlds):
        self.calls += 1
        if self.calls == self.kill_at_call:
            os.kill(os.getpid(), signal.SIGKILL)
        quality = 0.75 + 0.2 * params[:, :1]  # (b, 1): the first parameter makes a set robust
        success = np.asarray(worlds)[None, :] < quality
        ticks = np.where(success, 30 - (10 * params[:, 1:2]).astype(int), -1)
        return RolloutOutput(np.zeros((len(params), 1)), success, {"bt_done_tick": ticks})


def race_front(n=9) -> Evaluations:
    rng = np.random.default_rng(3)
    params = np.stack([np.linspace(0, 1, n), rng.random(n)], axis=1)
    objectives = np.stack([rng.random(n), rng.random(n), np.full(n, 0.76)], axis=1)
    return Evaluations(np.zeros(n, int), params, objectives, np.ones(n), np.zeros(n), np.zeros(n), rng.random(n) * 10)


RACE_SETTINGS = racing.race_settings(seed=4, engine="native", episode_seconds=3.0, episodes=200, max_force=None,
                                     n_configs=3)

KILLED_RACE = textwrap.dedent("""
    import sys
    from pathlib import Path
    sys.path[:0] = [{tests!r}, {helpers!r}]
    from test_robust_protocol import FakeRollout, RACE_SETTINGS, race_front
    from mjxskill.evaluation import racing
    racing.race(Path(sys.argv[1]), race_front(), FakeRollout(kill_at_call=int(sys.argv[2])), RACE_SETTINGS, 4)
""")


def test_the_race_halves_its_contenders_within_its_episodes_and_picks_the_robust_set(tmp_path):
    front = race_front()
    raced = racing.race(tmp_path, front, FakeRollout(), RACE_SETTINGS, batch_size=4)
    k, plan = racing.schedule(len(front), 3, 200)
    assert len(raced.contenders) == k and [len(r.rows) for r in raced.rounds] == [n for n, _ in plan]
    assert raced.episodes <= 200
    for earlier, later in zip(raced.rounds, raced.rounds[1:]):
        assert set(later.rows) <= set(earlier.rows)
    assert raced.winner >= len(front) - 3  # among the most robust sets (quality grows with the row)
    assert same_race(racing.load_race(tmp_path, front, RACE_SETTINGS), raced)


def test_schedule_fits_the_first_round_in_one_world_per_configuration():
    for n, c, e in ((13, 5, 420), (40, 4, 420), (2, 5, 10), (1, 5, 5)):
        k, plan = racing.schedule(n, c, e)
        assert 1 <= k <= n and plan[0] == (k, plan[0][1]) and plan[0][1] >= 1
        assert sum(size * per * c for size, per in plan) <= e
    assert racing.schedule(3, 5, 4) == (0, [])


def same_race(a: racing.Race, b: racing.Race) -> bool:
    return (a.contenders, a.winner, a.episodes) == (b.contenders, b.winner, b.episodes) and len(a.rounds) == len(
        b.rounds) and all(x.rows == y.rows and x.worlds == y.worlds and np.array_equal(x.successes, y.successes)
                          and np.array_equal(x.seconds, y.seconds) for x, y in zip(a.rounds, b.rounds))


def test_a_race_killed_between_rounds_resumes_to_the_same_pick(tmp_path):
    (tmp_path / "ref").mkdir()
    reference = racing.race(tmp_path / "ref", race_front(), FakeRollout(), RACE_SETTINGS, 4)
    cut = tmp_path / "cut"
    cut.mkdir()
    script = tmp_path / "kill_race.py"
    script.write_text(KILLED_RACE.format(tests=os.path.dirname(__file__), helpers=str(HELPERS)))
    done = subprocess.run([sys.executable, str(script), str(cut), "4"], capture_output=True, text=True, timeout=600)
    assert done.returncode == -signal.SIGKILL, done.stderr[-2000:]
    partial = json.loads((cut / racing.FILE).read_text())
    assert 0 < len(partial["rounds"]) < len(reference.rounds)
    resumed = racing.race(cut, race_front(), FakeRollout(), RACE_SETTINGS, 4)
    assert same_race(resumed, reference)
    assert (cut / racing.FILE).read_text() == (tmp_path / "ref" / racing.FILE).read_text()


def test_a_contender_whose_upper_bound_is_below_anothers_lower_bound_is_not_raced():
    # rows: 28 of 28, 7 of 7, 5 of 7, 2 of 7 (the last two cannot be the most successful)
    worlds = np.array([28, 7, 7, 7])
    rate = np.array([1.0, 1.0, 5 / 7, 2 / 7])
    bound = success_lower_bound(rate * worlds, worlds)
    front = Evaluations(np.zeros(4, int), np.zeros((4, 1)), np.stack([np.arange(4.0), bound], axis=1), rate,
                        np.zeros(4), np.zeros(4), np.array([1.0, 1.0, 1.0, 20.0]), worlds=worlds,
                        replaces=np.full(4, -1), spread=np.zeros((4, 2)))
    assert success_upper_bound(5, 7) < success_lower_bound(28, 28) < success_upper_bound(7, 7)
    assert racing.contenders(front, None) == [0, 1]
    assert racing.contenders(front, 10.0) == [0, 1]
    # within a bound that excludes the best, the others are measured against what is left
    assert racing.contenders(front.take([1, 2, 3]), None) == [0, 1]
