"""The optimizers behind one interface (``mjxskill.training.optimizers``): a factory per run
setting, the name refused as the setting refuses it, the shared warm-up, pure proposals, and the
loop refusing an optimizer that is not the run's. No physics: the toy configuration of the loop's
tests."""

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from mjxskill import gp
from mjxskill.runs.settings import OPTIMIZERS
from mjxskill.training.loop import train
from mjxskill.training.optimizers import FACTORIES, make_optimizer
from toy_runs import CONFIG, new_run, toy_objective


def test_one_factory_per_optimizer_setting():
    assert tuple(FACTORIES) == OPTIMIZERS
    for name in OPTIMIZERS:
        assert make_optimizer(name, CONFIG).name == name


def test_an_unknown_name_is_refused_as_the_setting_refuses_it():
    with pytest.raises(ValueError, match=r"^expected one of mobo, random, optuna-nsga2, .*, got 'gp'$"):
        make_optimizer("gp", CONFIG)


@pytest.mark.parametrize("name", ["mobo", "random"])
def test_the_warm_up_is_the_bayesian_optimizers_then_asking_is_pure(name):
    optimizer = make_optimizer(name, CONFIG)
    state = optimizer.init()
    first = optimizer.ask(state, 4)
    np.testing.assert_array_equal(first, gp.ask(gp.init(state.config), num=4))
    state = optimizer.tell(state, first, -toy_objective(first, 0).objectives)
    x = optimizer.ask(state, 2)
    state = optimizer.tell(state, x, -toy_objective(x, 1).objectives)
    assert len(state.x) == CONFIG.n_init
    np.testing.assert_array_equal(optimizer.ask(state, 4), optimizer.ask(state, 4))


def test_train_refuses_an_optimizer_that_is_not_the_runs(tmp_path):
    with pytest.raises(ValueError, match="'random' is not the run's, 'mobo'"):
        train(new_run(tmp_path, "run"), CONFIG, toy_objective, optimizer=make_optimizer("random", CONFIG))


def test_building_an_optimizer_imports_no_jax_before_it_is_used():
    code = ("import sys\n"
            "import mjxskill.gp, mjxskill.training.optimizers, mjxskill.training.loop\n"
            "from mjxskill.gp import hypervolume, pareto_mask, AcquisitionSettings\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('jax', 'optuna', 'torch')))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_a_random_search_of_another_seed_draws_otherwise():
    other = replace(CONFIG, seed=CONFIG.seed + 1)
    states = []
    for config in (CONFIG, other):
        optimizer = make_optimizer("random", config)
        state = optimizer.init()
        x = optimizer.ask(state, 6)
        states.append((optimizer, optimizer.tell(state, x, -toy_objective(x, 0).objectives)))
    a, b = (optimizer.ask(state, 4) for optimizer, state in states)
    assert not np.allclose(a, b)
