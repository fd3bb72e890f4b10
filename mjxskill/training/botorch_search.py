"""BoTorch's qLogNEHVI as a run's optimizer (``optimizer: botorch-qlognehvi``), in the run's own
loop and batches: what a user who knows BoTorch would run instead of ours, on their own cell.

As for Optuna's samplers (``mjxskill.training.optuna_search``), the run's optimizer
(``mjxskill.training.optimizers.botorch_qlognehvi``) asks this module only after the warm-up,
whose rows are the Bayesian optimizer's own uniform draws, so runs of one seed share them. Each
batch is BoTorch's multi-objective tutorial (``mjxskill.training.botorch_tutorial``), unchanged
but for the reference:

* the model: one ``SingleTaskGP`` per objective (BoTorch's default priors, outputs
  standardized), fitted by marginal likelihood on the rows so far, the parameters scaled to the
  unit cube by the run's bounds; rows with a non-finite objective (a diverged world) left out;
* the acquisition: ``qLogNoisyExpectedHypervolumeImprovement`` with 128 quasi-Monte Carlo
  samples about the run's reference point, the one ``train`` reports its hypervolume against and
  ours optimizes about (the worst warm-up value plus 10 % of the warm-up's range), all the rows
  as the noisy baseline;
* the batch: ``optimize_acqf`` with ``sequential=True`` (q candidates one after the other, each
  conditioned on the ones before), 10 restarts from 512 raw samples, L-BFGS-B 200 steps.

Torch's generator is seeded from (seed, number of rows) before every batch, so a resumed run
proposes what an uninterrupted one did (on the same machine: torch's CPU kernels are
deterministic there). BoTorch and PyTorch are an optional extra (``pip install
'mjxskill[botorch]'``), imported by ``botorch_tutorial`` alone: this module imports without
them. ``mjxskill.training.extras.missing_extra`` says what to install when they are absent.
"""

from __future__ import annotations

import numpy as np

from mjxskill.runs.run_config import RunConfig
from mjxskill.training.front import hypervolume_reference

OPTIMIZER = "botorch-qlognehvi"
SEED_STREAM = 0xB07C  # separates the batches' seeds from every other use of the run's seed


def batch_seed(seed: int, rows: int) -> int:
    """Torch's seed for the batch after ``rows`` rows: (seed, rows) and nothing else."""
    return int(np.random.SeedSequence([seed, SEED_STREAM, rows]).generate_state(1)[0])


def reference_point(config: RunConfig, objectives: np.ndarray) -> np.ndarray:
    """(O,) the run's reference in the objectives (larger is better): the warm-up's worst value
    of each minus 10 % of its range (``mjxskill.training.front.hypervolume_reference``)."""
    return -hypervolume_reference(objectives[: config.n_init])


def ask(config: RunConfig, params: np.ndarray, objectives: np.ndarray, size: int) -> np.ndarray:
    """The next ``size`` parameter sets (size, P) after the rows ``params`` (n, P) and
    ``objectives`` (n, O, larger is better) so far."""
    # lazy: BoTorch and PyTorch, an optional extra (torch takes seconds to import); configure
    # refuses the run without it, and the tests of this module's other functions run without it
    from mjxskill.training import botorch_tutorial

    lo, hi = (np.asarray(b, np.float64) for b in config.bounds)
    params, objectives = np.asarray(params, np.float64), np.asarray(objectives, np.float64)
    ok = np.all(np.isfinite(objectives), axis=1)
    cand = botorch_tutorial.next_batch((params[ok] - lo) / (hi - lo), objectives[ok],
                                       reference_point(config, objectives).tolist(), size,
                                       batch_seed(config.seed, len(params)))
    u = np.clip(cand, 0.0, 1.0)
    return lo + u * (hi - lo)


__all__ = ["OPTIMIZER", "ask", "batch_seed", "reference_point"]
