"""The optimizer loop of a run: propose a batch, evaluate it, write it, repeat to the budget.

Scenario -> plan -> eBT -> compiled rollout -> optimizer loop. Every batch is appended to
``evaluations.csv`` and flushed before the next proposal; the optimizer state is replayed from
that file on resume (see ``mjxskill.training.run_dir``), so an interrupted run continues to the
same budget and ends with the results of an uninterrupted one.
"""

from __future__ import annotations

from typing import Callable, NamedTuple, Protocol

import numpy as np

from mjxskill.training.front import pareto_mask_of, reference_from
from mjxskill.training.run_dir import OPTIMIZER_STATE, Evaluations, Run, RunConfig, batch_sizes


class BatchResult(NamedTuple):
    """What one evaluated batch of B parameter sets gives: objectives (B, O), larger is better;
    success_rate (B,) in [0, 1]; max_force (B,) N."""

    objectives: np.ndarray
    success_rate: np.ndarray
    max_force: np.ndarray


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
    import jax

    return jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(seed), 0x0ED0), iteration)


def rollout_evaluator(rollout, batch_size: int, seed: int) -> BatchEvaluator:
    """Evaluates batches with a compiled rollout, always at ``batch_size`` parameter sets (short
    batches are padded with copies of their first row) so that a run compiles once."""

    def evaluate(params: np.ndarray, iteration: int) -> BatchResult:
        n = len(params)
        padded = np.concatenate([params, np.repeat(params[:1], batch_size - n, axis=0)])
        out = rollout(padded, rollout_key(seed, iteration))
        success = np.asarray(out.success, np.float64)[:n]
        return BatchResult(
            objectives=np.asarray(out.objectives, np.float64)[:n],
            success_rate=success.mean(axis=1),
            max_force=np.asarray(out.metrics["max_force"], np.float64)[:n].mean(axis=1),
        )

    return evaluate


def optimizer_config(config: RunConfig):
    """The ``mjxskill.gp.MOBOConfig`` of a run: its parameter space, batches and seed, and the
    further optimizer options it was started with."""
    from mjxskill.gp import MOBOConfig

    return MOBOConfig(
        bounds=config.bounds,
        n_objectives=len(config.objective_names),
        batch_size=config.batch_size,
        n_init=config.n_init,
        seed=config.seed,
        **config.optimizer_options,
    )


def train(run: Run, config: RunConfig, evaluate: BatchEvaluator, *, progress: Progress | None = None) -> Evaluations:
    """Runs (or continues) the optimizer loop of ``run`` to ``config.budget`` evaluations.

    The optimizer state is replayed from the rows on disk; each batch is appended and flushed
    before the next proposal. Returns all evaluations.
    """
    from mjxskill import gp

    ev = run.repair(config)
    state = gp.init(optimizer_config(config))
    if len(ev):
        state = gp.tell(state, ev.params, -ev.objectives)
    sizes = list(batch_sizes(config.budget, config.batch_size, config.n_init))
    batch = int(np.searchsorted(np.cumsum(sizes), len(ev), side="right"))
    if progress:
        progress.start(ev, reference_from(run, config, ev))
    while len(ev) < config.budget:
        x = gp.ask(state, num=sizes[batch])
        result = evaluate(x, batch)
        new = Evaluations(np.full(len(x), batch), x, *(np.asarray(a, np.float64) for a in result))
        run.append(new)  # on disk before anything else happens
        ev = ev.concat(new)
        state = gp.tell(state, x, -new.objectives)
        gp.save_state(state, run.path / OPTIMIZER_STATE)
        run.write_pareto(config, ev, pareto_mask_of(ev))
        if progress:
            progress.update(new, ev, reference_from(run, config, ev))
        batch += 1
    run.write_pareto(config, ev, pareto_mask_of(ev))
    if progress:
        progress.close()
    return ev
