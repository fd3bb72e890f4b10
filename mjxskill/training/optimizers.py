"""The optimizers a run trains with, behind one interface (in optax's style: an optimizer is a
value that a factory builds, and ``init``/``ask``/``tell`` are all the loop knows of it).

    optimizer = make_optimizer(config.optimizer, config)   # or gp_optimizer(config), ...
    state = optimizer.init()
    x = optimizer.ask(state, size)                          # (size, P) parameter sets
    state = optimizer.tell(state, x, -objectives)           # objectives minimized, as gp's

One factory per method, ``FACTORIES`` by the name a run's ``optimizer`` setting takes
(``mjxskill.runs.settings.OPTIMIZERS``): ``gp_optimizer`` (``mobo``, the Bayesian optimizer of
``mjxskill.gp``), ``random_search`` (``random``: uniform draws from the bounds),
``optuna_sampler`` (``optuna-*``, ``mjxskill.training.optuna_search``) and ``botorch_qlognehvi``
(``botorch-qlognehvi``, ``mjxskill.training.botorch_search``).

The state of every optimizer is gp's ``MOBOState`` of the run's ``MOBOConfig``: the rows told so
far (objectives minimized, with their noise variances where the rows pool several worlds), which
the loop writes as ``optimizer_state.npz``. Every optimizer proposes its first ``n_init`` rows
with the Bayesian optimizer's own uniform warm-up (``gp.ask``), so runs of one seed share those
rows and part where the optimizers take over. Every proposal is a function of the rows told and
the run's seed alone, so a resumed run, its state told again from its rows, proposes the batches
an uninterrupted run did. Nothing here imports jax until an optimizer is used (``mjxskill.gp``
loads its names lazily), nor Optuna or BoTorch until they propose.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Callable, Protocol

import numpy as np

from mjxskill import gp
from mjxskill.errors import quote
from mjxskill.runs.run_config import RunConfig, optimizer_config
from mjxskill.runs.settings import BOTORCH_OPTIMIZERS, BY_NAME, OPTUNA_OPTIMIZERS
from mjxskill.training import botorch_search, optuna_search

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.gp import MOBOState

RANDOM_SEARCH_STREAM = 0x5EA2C  # separates random search's draws from every other use of the seed


class Optimizer(Protocol):
    """What the training loop asks of an optimizer."""

    @property
    def name(self) -> str:
        """The run setting it is (``config.yaml``'s ``optimizer``)."""
        ...

    def init(self) -> MOBOState:
        """The state of a run that has told nothing yet."""
        ...

    def ask(self, state: MOBOState, size: int) -> np.ndarray:
        """The next ``size`` parameter sets (size, P) after the rows of ``state``; pure (asking
        twice without telling gives the same batch)."""
        ...

    def tell(self, state: MOBOState, x: np.ndarray, y: np.ndarray, noise: np.ndarray | None = None) -> MOBOState:
        """``state`` with the rows ``x`` (q, P), ``y`` (q, O; minimized) appended, and their noise
        variances ``noise`` (q, O) where the state's rows have them."""
        ...


# (state past the warm-up, size) -> the next size parameter sets
Proposal = Callable[["MOBOState", int], np.ndarray]


@dataclass(frozen=True)
class WarmedUp:
    """An optimizer of a run: the Bayesian optimizer's warm-up (``gp.ask``) until the state holds
    ``n_init`` rows, then ``propose`` (None: ``gp.ask`` throughout, the Bayesian optimizer). Its
    state is gp's, of ``config``."""

    name: str
    config: gp.MOBOConfig
    propose: Proposal | None = None

    def init(self) -> MOBOState:
        return gp.init(self.config)

    def ask(self, state: MOBOState, size: int) -> np.ndarray:
        if self.propose is None or len(state.x) < self.config.n_init:
            return gp.ask(state, num=size)
        return self.propose(state, size)

    def tell(self, state: MOBOState, x: np.ndarray, y: np.ndarray, noise: np.ndarray | None = None) -> MOBOState:
        return gp.tell(state, x, y, noise)


def gp_optimizer(config: RunConfig) -> Optimizer:
    """``mobo``: the multi-objective Bayesian optimizer of ``mjxskill.gp`` with the run's
    acquisition settings and prior (``runs.run_config.optimizer_config``)."""
    return WarmedUp("mobo", optimizer_config(config))


def random_search(config: RunConfig) -> Optimizer:
    """``random``: after the warm-up, uniform draws from the bounds with a generator seeded by
    (seed, rows so far)."""
    lo, hi = np.asarray(config.bounds, np.float64)

    def propose(state: MOBOState, size: int) -> np.ndarray:
        u = np.random.default_rng([config.seed, RANDOM_SEARCH_STREAM, len(state.x)]).random((size, len(lo)))
        return lo + u * (hi - lo)

    return WarmedUp("random", optimizer_config(config), propose)


def optuna_sampler(config: RunConfig) -> Optimizer:
    """``optuna-nsga2``, ``optuna-tpe``, ``optuna-gp`` (``config.optimizer``): after the warm-up,
    Optuna's sampler on a study rebuilt from the rows so far (``optuna_search.ask``)."""
    if config.optimizer not in OPTUNA_OPTIMIZERS:
        raise ValueError(f"{quote(config.optimizer)} is none of Optuna's optimizers {', '.join(OPTUNA_OPTIMIZERS)}")
    return WarmedUp(config.optimizer, optimizer_config(config),
                    lambda state, size: optuna_search.ask(config, state.x, -state.y, size))


def botorch_qlognehvi(config: RunConfig) -> Optimizer:
    """``botorch-qlognehvi``: after the warm-up, BoTorch's qLogNEHVI from models fitted on the
    rows so far (``botorch_search.ask``)."""
    return WarmedUp(botorch_search.OPTIMIZER, optimizer_config(config),
                    lambda state, size: botorch_search.ask(config, state.x, -state.y, size))


FACTORIES: dict[str, Callable[[RunConfig], Optimizer]] = {
    "mobo": gp_optimizer,
    "random": random_search,
    **dict.fromkeys(OPTUNA_OPTIMIZERS, optuna_sampler),
    **dict.fromkeys(BOTORCH_OPTIMIZERS, botorch_qlognehvi),
}


def make_optimizer(name: str, config: RunConfig) -> Optimizer:
    """The optimizer ``name`` (one of ``OPTIMIZERS``) of the run ``config``, as if the run's
    ``optimizer`` setting were ``name``. An unknown name is the ValueError of that setting's
    check (as ``--optimizer`` and ``config.yaml`` refuse it: ``expected one of mobo, random, ...``)."""
    BY_NAME["optimizer"].coerce(name)
    return FACTORIES[name](config if config.optimizer == name else replace(config, optimizer=name))


__all__ = ["FACTORIES", "Optimizer", "RANDOM_SEARCH_STREAM", "WarmedUp", "botorch_qlognehvi", "gp_optimizer",
           "make_optimizer", "optuna_sampler", "random_search"]
