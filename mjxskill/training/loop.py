"""The optimizer loop of a run: propose a batch, evaluate it, write it, repeat to the budget.

Scenario -> plan -> eBT -> compiled rollout -> optimizer loop (the Bayesian optimizer, or what it
is compared with: uniform random search, Optuna's samplers or BoTorch's qLogNEHVI, each an
``Optimizer`` of ``mjxskill.training.optimizers``). Every batch is appended to
``evaluations.csv`` and flushed before the next proposal; the optimizer state is replayed from
that file on resume (see ``mjxskill.runs.run_dir``), so an interrupted run continues to the
same budget and ends with the results of an uninterrupted one.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, NamedTuple, Protocol

import numpy as np

from mjxskill import gp
from mjxskill.engine.common.keys import stream_key
from mjxskill.errors import quote
from mjxskill.runs.atomic_write import replace_whole
from mjxskill.training.front import pareto_mask_of, reference_from
from mjxskill.runs.evaluations_csv import FORCE_COLUMNS
from mjxskill.runs.resume import resume_batches
from mjxskill.runs.run_dir import EVALUATIONS, OPTIMIZER_STATE, Evaluations, Run, RunConfig, batch_sizes, concat_all
from mjxskill.runs.training_protocol import REPLICATIONS_PER_BATCH
from mjxskill.training import replication
from mjxskill.training.optimizers import Optimizer, make_optimizer

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.protocol import Rollout


class BatchResult(NamedTuple):
    """What one evaluated batch of B parameter sets gives: objectives (B, O), larger is better
    (the scenario's: a run of the robust protocol adds the success bound itself); success_rate
    (B,) in [0, 1]; peak_contact_force, mean_contact_force, peak_commanded_force (B,) N, means
    over the worlds (``Evaluations``); spread (B, O): each objective's world-to-world standard
    deviation (ddof 1), and worlds: how many worlds each set was rolled out in (what the robust
    protocol pools; None: not given)."""

    objectives: np.ndarray
    success_rate: np.ndarray
    peak_contact_force: np.ndarray
    mean_contact_force: np.ndarray
    peak_commanded_force: np.ndarray
    spread: np.ndarray | None = None
    worlds: int | None = None


# (params (B, P) float64, batch index) -> BatchResult. Must be a pure function of its inputs:
# resuming relies on a re-run batch giving the same numbers.
BatchEvaluator = Callable[[np.ndarray, int], BatchResult]


class Progress(Protocol):
    """What the loop reports to (the command line's progress bar)."""

    def start(self, ev: Evaluations, reference: np.ndarray | None) -> None: ...

    def update(self, new: Evaluations, ev: Evaluations, reference: np.ndarray | None) -> None: ...

    def close(self) -> None: ...


def rollout_key(seed: int, iteration: int):
    """PRNG key of batch ``iteration``'s worlds: depends only on (seed, batch index), so a
    resumed run draws the same worlds. A stream separate from the optimizer's keys."""
    return stream_key(seed, 0x0ED0, iteration)


def rollout_evaluator(rollout: Rollout, batch_size: int, seed: int) -> BatchEvaluator:
    """Evaluates batches with a compiled rollout, always at ``batch_size`` parameter sets (short
    batches are padded with copies of their first row) so that a run compiles once."""

    def evaluate(params: np.ndarray, iteration: int) -> BatchResult:
        n = len(params)
        padded = np.concatenate([params, np.repeat(params[:1], batch_size - n, axis=0)])
        out = rollout(padded, rollout_key(seed, iteration))
        success = np.asarray(out.success, np.float64)[:n]
        forces = {name: np.asarray(out.metrics[name], np.float64)[:n].mean(axis=1) for name in FORCE_COLUMNS}
        per_world = world_objectives(rollout, out)[:n]
        spread = per_world.std(axis=1, ddof=1) if per_world.shape[1] > 1 else np.full(per_world.shape[::2], np.nan)
        return BatchResult(objectives=np.asarray(out.objectives, np.float64)[:n], success_rate=success.mean(axis=1),
                           **forces, spread=spread, worlds=success.shape[1])

    return evaluate


def world_objectives(rollout: Rollout, out) -> np.ndarray:
    """(B, W, O) each world's objectives (the sums of their weighted rewards; ``out.objectives``
    is their mean over the W worlds), from the per-world reward totals of ``out``."""
    names = tuple(rollout.objective_names)
    first = np.asarray(out.success)
    values = np.zeros(first.shape + (len(names),))
    for reward in rollout.scenario.rewards:
        values[..., names.index(reward.objective)] += reward.weight * np.asarray(out.metrics[f"reward_{reward.name}"],
                                                                                 np.float64)
    return values


def train(run: Run, config: RunConfig, evaluate: BatchEvaluator, *, progress: Progress | None = None,
          optimizer: Optimizer | None = None) -> Evaluations:
    """Runs (or continues) the optimizer loop of ``run`` to ``config.training_rows`` evaluations.

    The complete batches on disk are kept (``mjxskill.runs.resume``: what cannot be used is
    set aside, never dropped) and only the missing ones are evaluated. The optimizer state is
    replayed batch by batch in batch order, so every proposal is the one an uninterrupted run
    makes; each new batch is on disk before the next proposal. ``optimizer``: what proposes the
    batches (default: ``make_optimizer(config.optimizer, config)``; one of another name is refused,
    the run's rows being its optimizer's). Returns all evaluations.
    """
    done = resume_batches(run, config)
    shape = (len(config.parameter_names), len(config.objective_names), config.pooled)
    if optimizer is None:
        optimizer = make_optimizer(config.optimizer, config)
    elif optimizer.name != config.optimizer:
        raise ValueError(f"train: the optimizer {quote(optimizer.name)} is not the run's, {quote(config.optimizer)}")
    state = optimizer.init()
    sizes = list(batch_sizes(config.training_rows, config.batch_size, config.n_init))
    known = lambda: concat_all((done[b] for b in sorted(done)), *shape)  # noqa: E731  (in batch order)
    ev = known()
    replication.check_pointers(ev, str(run.path / EVALUATIONS))
    if progress:
        progress.start(ev, reference_from(run, config, ev))
    saved = False  # whether the optimizer state on disk is that of every batch
    for batch, size in enumerate(sizes):
        if config.pooled:  # the rows so far pooled, each with its noise (mjxskill.training.replication)
            if batch in done:
                continue
            earlier = concat_all((done[b] for b in range(batch)), *shape)
            state = _pooled_state(optimizer, earlier)
            new = done[batch] = _pooled_batch(optimizer, state, config, earlier, batch, size, evaluate)
            x = new.params
        elif batch in done:  # replayed: the optimizer sees it where the uninterrupted run did
            state = optimizer.tell(state, done[batch].params, -done[batch].objectives)
            continue
        else:
            x = optimizer.ask(state, size)
            result = evaluate(x, batch)
            new = done[batch] = Evaluations(np.full(len(x), batch), x, *(np.asarray(a, np.float64) for a in result[:5]))
        ev = known()
        if max(done) == batch:
            run.append(new)  # on disk before anything else happens
        else:  # filled in before batches already on disk: the file stays in batch order
            run.write_evaluations(config, ev)
        state = _pooled_state(optimizer, ev) if config.pooled else optimizer.tell(state, x, -new.objectives)
        _save_state(state, run.path / OPTIMIZER_STATE)
        saved = batch == len(sizes) - 1
        run.write_pareto(config, ev, pareto_mask_of(ev))
        if progress:
            progress.update(new, ev, reference_from(run, config, ev))
    if not saved and done:  # a run killed between its last batch's rows and their state: the state is written now
        _save_state(_pooled_state(optimizer, ev) if config.pooled else state, run.path / OPTIMIZER_STATE)
    run.write_pareto(config, ev, pareto_mask_of(ev))
    if progress:
        progress.close()
    return ev


REPLICATION_STREAM = 0x2E911  # the success model's fits that choose what to roll out again


def _pooled_state(optimizer: Optimizer, ev: Evaluations):
    """The optimizer state of a pooled run's current rows: their objectives and success rates,
    each with its noise variance (``replication.model_view``)."""
    if not len(ev):
        return optimizer.init()
    x, values, noise = replication.model_view(ev)
    return optimizer.tell(optimizer.init(), x, -values, noise=noise)


def _pooled_batch(optimizer: Optimizer, state, config: RunConfig, earlier: Evaluations, batch: int, size: int,
                  evaluate: BatchEvaluator) -> Evaluations:
    """Batch ``batch`` of a pooled run: after the warm-up, REPLICATIONS_PER_BATCH of its places
    roll out again the sets ``replication.choose`` names (the Bayesian optimizer's runs only:
    what it is compared with proposes as it would alone), the others new proposals; the rows of
    the first pool their earlier worlds."""
    again = np.zeros(0, int)
    if optimizer.name == "mobo" and len(state.x) >= config.n_init and size > 1:
        key = stream_key(config.seed, REPLICATION_STREAM, batch)
        again = replication.choose(earlier, min(REPLICATIONS_PER_BATCH, size - 1), config.worlds, config.bounds, key)
    x = optimizer.ask(state, size - len(again))
    result = evaluate(np.concatenate([x, earlier.params[again]]), batch)
    k = len(x)
    objectives = np.asarray(result.objectives, np.float64)
    # an evaluator that gives no spread: the rows' noise is the fitted one alone (replication.noise_variances)
    spread = np.full(objectives.shape, np.nan) if result.spread is None else np.asarray(result.spread, np.float64)
    worlds = config.worlds if result.worlds is None else result.worlds
    parts = [replication.PooledResult(objectives[s], spread[s], np.asarray(result.success_rate, np.float64)[s],
                                      tuple(np.asarray(f, np.float64)[s] for f in result[2:5]), worlds)
             for s in (slice(0, k), slice(k, None))]
    new = replication.new_rows(batch, x, parts[0])
    return new.concat(replication.pooled_rows(batch, earlier, again, parts[1])) if len(again) else new


def _save_state(state, path) -> None:
    """The optimizer state, replaced in one step (a kill mid-write leaves the previous one)."""
    replace_whole(path, lambda fh: gp.save_state(state, fh))
