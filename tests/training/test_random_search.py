"""``train --optimizer random``: uniform random search as a run like any other, with the
optimizer's batches and warm-up, seeded, replayed on resume (closed-form objective, no physics)."""

from dataclasses import replace

import numpy as np
import pytest
import yaml
from scipy.stats import kstest

from mjxskill import gp
from mjxskill.cli.progress import Progress
from mjxskill.training.loop import train
from mjxskill.runs.run_dir import EVALUATIONS, RunConfig
from toy_runs import CONFIG, Recorder, new_run, toy_objective

RANDOM = replace(CONFIG, optimizer="random")


@pytest.fixture(scope="module")
def optimizer_ev(tmp_path_factory):
    """The Bayesian optimizer's rows of the same configuration and seed."""
    return train(new_run(tmp_path_factory.mktemp("mobo"), "mobo"), CONFIG, toy_objective)


def test_random_search_shares_the_warm_up_then_draws_without_the_model(tmp_path, monkeypatch, optimizer_ev):
    asked = []
    real_ask = gp.ask
    monkeypatch.setattr(gp, "ask", lambda state, num=None: asked.append(len(state.x)) or real_ask(state, num))
    run = new_run(tmp_path, "random", RANDOM)
    recorder = Recorder()
    ev = train(run, RANDOM, recorder, progress=Progress(RANDOM.budget, quiet=True))
    # the same batches as the optimizer's: 4 + 2 warm-up, then 4
    assert [len(x) for _, x in recorder.calls] == [4, 2, 4] and list(ev.iteration) == list(optimizer_ev.iteration)
    # the warm-up is the optimizer's own (asked from it), the rest never is
    assert asked == [0, 4]
    np.testing.assert_array_equal(ev.params[:6], optimizer_ev.params[:6])
    assert not np.allclose(ev.params[6:], optimizer_ev.params[6:])
    lo, hi = np.asarray(RANDOM.bounds)
    assert np.all((ev.params >= lo) & (ev.params <= hi))


def test_random_search_resumes_to_the_same_rows(tmp_path):
    full = new_run(tmp_path, "full", RANDOM)
    train(full, RANDOM, Recorder())
    cut = new_run(tmp_path, "cut", RANDOM)
    with pytest.raises(KeyboardInterrupt):
        train(cut, RANDOM, Recorder(stop_after=2))
    second = Recorder()
    train(cut, RANDOM, second)
    assert [it for it, _ in second.calls] == [2]
    assert (cut.path / EVALUATIONS).read_text() == (full.path / EVALUATIONS).read_text()


def test_random_search_is_uniform_over_the_bounds_and_seeded(tmp_path):
    # 300 draws after a 6-point warm-up, no model: each coordinate uniform on its interval
    big = replace(RANDOM, budget=306, batch_size=50)
    ev = train(new_run(tmp_path, "big", big), big, toy_objective)
    lo, hi = np.asarray(big.bounds)
    u = (ev.params[6:] - lo) / (hi - lo)
    for d in range(u.shape[1]):
        assert kstest(u[:, d], "uniform").pvalue > 1e-3
    other = replace(big, seed=big.seed + 1)
    ev2 = train(new_run(tmp_path, "other", other), other, toy_objective)
    assert not np.allclose(ev.params[6:], ev2.params[6:])  # another seed, other draws


def test_the_optimizer_is_stored_and_an_older_config_is_the_bayesian_one():
    data = yaml.safe_load(RANDOM.to_yaml())
    assert data["optimizer"] == "random"
    assert RunConfig.from_yaml(RANDOM.to_yaml(), "run/config.yaml") == RANDOM
    del data["optimizer"]  # written before the setting existed
    assert RunConfig.from_yaml(yaml.safe_dump(data, sort_keys=False), "old/config.yaml").optimizer == "mobo"
