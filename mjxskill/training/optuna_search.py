"""Optuna's multi-objective samplers as a run's optimizer (``optimizer: optuna-nsga2``,
``optuna-tpe`` or ``optuna-gp``), driven by ask/tell in the run's own loop and batches.

The run's optimizer (``mjxskill.training.optimizers.optuna_sampler``) asks this module for a
batch only after the warm-up. The warm-up is the same for every optimizer: its first ``n_init``
rows are the Bayesian optimizer's own uniform draws (``mjxskill.gp.ask``, with the run's prior if
it has one), so runs of one seed with different optimizers share those rows and part where the
optimizers take over.
Each sampler's own start-up (random trials before its model) is set to ``n_init``, so that it
models from the first batch after the warm-up, as ours does.

Before every batch a study is rebuilt in memory from the rows so far (each row a finished
trial: the parameters as ``FloatDistribution`` over the run's bounds, the objectives maximized,
as the rows store them larger-is-better; a row with a non-finite objective, a diverged world, a
failed trial), the sampler is seeded from (seed, number of rows), and the batch's trials are
asked one after the other, none told before the batch is evaluated. The proposals are thus a
function of the rows and the seed alone: a resumed run proposes what an uninterrupted run did,
and nothing of Optuna's is kept on disk (the rows are ``evaluations.csv``).

The samplers, otherwise at Optuna's defaults:

* ``optuna-nsga2``: ``NSGAIISampler`` with a population of ``n_init`` (the warm-up is its first
  generation). A trial's generation is stored in the trial by Optuna when asked; the rebuilt
  study recomputes it batch by batch with Optuna's rule (a batch gets the newest generation of
  the finished trials, or the next one when that generation has a full population);
* ``optuna-tpe``: ``TPESampler(multivariate=True, constant_liar=True)``, constant liar being
  Optuna's way of asking several trials before telling any;
* ``optuna-gp``: ``GPSampler`` (log expected hypervolume improvement, the trials asked but not
  told taken as pending); needs PyTorch.

Optuna is an optional extra (``pip install 'mjxskill[optuna]'``, with PyTorch
``'mjxskill[optuna-gp]'``); ``mjxskill.training.extras.missing_extra`` says what to install
when it is absent.
"""

from __future__ import annotations

import contextlib
import warnings

import numpy as np

from mjxskill.errors import quote
from mjxskill.runs.run_config import RunConfig, batch_sizes
from mjxskill.runs.settings import OPTUNA_OPTIMIZERS

SAMPLER_STREAM = 0x0B7A  # separates the samplers' seeds from every other use of the run's seed


def sampler_seed(seed: int, rows: int) -> int:
    """The sampler's seed for the batch after ``rows`` rows: (seed, rows) and nothing else."""
    return int(np.random.SeedSequence([seed, SAMPLER_STREAM, rows]).generate_state(1)[0])


def ask(config: RunConfig, params: np.ndarray, objectives: np.ndarray, size: int) -> np.ndarray:
    """The next ``size`` parameter sets (size, P) of ``config``'s Optuna sampler after the rows
    ``params`` (n, P) and ``objectives`` (n, O, larger is better) of the batches so far, in batch
    order (the batches of ``batch_sizes``)."""
    # lazy: an optional extra (and ~1 s to import); configure refuses the run before this without it
    import optuna

    names = list(config.parameter_names)
    lo, hi = (np.asarray(b, np.float64) for b in config.bounds)
    distributions = {name: optuna.distributions.FloatDistribution(float(a), float(b))
                     for name, a, b in zip(names, lo, hi)}
    with _quiet(optuna):
        sampler = _sampler(optuna, config, sampler_seed(config.seed, len(params)))
        study = optuna.create_study(directions=["maximize"] * len(config.objective_names), sampler=sampler)
        generations = _generations(config, objectives) if config.optimizer == "optuna-nsga2" else None
        key = sampler._get_generation_key() if generations is not None else None
        study.add_trials([_trial(optuna, dict(zip(names, np.clip(x, lo, hi).tolist())), y, distributions,
                                 # key: NSGA-II's, with generations
                                 {key: generations[i]} if key else {})  # type: ignore[index]
                          for i, (x, y) in enumerate(zip(params, objectives))])
        # optuna annotates dict, not Mapping
        trials = [study.ask(distributions) for _ in range(size)]  # type: ignore[arg-type]
    return np.array([[t.params[name] for name in names] for t in trials], np.float64).reshape(size, len(names))


def _sampler(optuna, config: RunConfig, seed: int):
    if config.optimizer == "optuna-nsga2":
        return optuna.samplers.NSGAIISampler(population_size=config.n_init, seed=seed)
    if config.optimizer == "optuna-tpe":
        return optuna.samplers.TPESampler(multivariate=True, constant_liar=True, n_startup_trials=config.n_init,
                                          seed=seed)
    if config.optimizer == "optuna-gp":
        return optuna.samplers.GPSampler(n_startup_trials=config.n_init, seed=seed)
    raise ValueError(f"{quote(config.optimizer)} is none of Optuna's optimizers {', '.join(OPTUNA_OPTIMIZERS)}")


def _trial(optuna, params: dict, values: np.ndarray, distributions: dict, system_attrs: dict):
    """One evaluated row as a finished trial: complete, or failed when an objective is not finite."""
    finite = bool(np.all(np.isfinite(values)))
    state = optuna.trial.TrialState.COMPLETE if finite else optuna.trial.TrialState.FAIL
    return optuna.trial.create_trial(state=state, values=[float(v) for v in values] if finite else None,
                                     params=params, distributions=distributions, system_attrs=system_attrs)


def _generations(config: RunConfig, objectives: np.ndarray) -> list[int]:
    """NSGA-II's generation of each row, as the sampler assigns it when a batch is asked: the
    newest generation among the complete trials before the batch (0 when none), or the next one
    when that generation already holds ``population_size`` complete trials. Failed trials have a
    generation but do not count towards a population, as in Optuna."""
    complete = np.all(np.isfinite(objectives), axis=1)
    generations: list[int] = []
    newest, count = 0, 0
    sizes = batch_sizes(config.training_rows, config.batch_size, config.n_init)
    while len(generations) < len(objectives):
        size = next(sizes)
        generation = newest + 1 if count >= config.n_init else newest
        rows = range(len(generations), min(len(generations) + size, len(objectives)))
        generations += [generation] * len(rows)
        done = sum(bool(complete[i]) for i in rows)
        if done and generation > newest:
            newest, count = generation, done
        elif generation == newest:
            count += done
    return generations


@contextlib.contextmanager
def _quiet(optuna):
    """Optuna's notes on every rebuilt study (a study created, a feature experimental) held back:
    they would repeat each batch. Its log level is the caller's again afterwards."""
    level = optuna.logging.get_verbosity()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            yield
    finally:
        optuna.logging.set_verbosity(level)


__all__ = ["OPTUNA_OPTIMIZERS", "ask", "sampler_seed"]
