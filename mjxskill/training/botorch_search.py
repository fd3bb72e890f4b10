"""BoTorch's qLogNEHVI as a run's optimizer (``optimizer: botorch-qlognehvi``), in the run's own
loop and batches: what a user who knows BoTorch would run instead of ours, on their own cell.

As for Optuna's samplers (``mjxskill.training.optuna_search``), the loop asks this module only
after the warm-up, whose rows are the Bayesian optimizer's own uniform draws, so runs of one seed
share them. Each batch is BoTorch's multi-objective tutorial, unchanged but for the reference:

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
'mjxskill[botorch]'``); ``mjxskill.training.extras.missing_extra`` says what to install when
they are absent.
"""

from __future__ import annotations

import contextlib
import warnings

import numpy as np

from mjxskill.runs.run_config import RunConfig
from mjxskill.training.front import hypervolume_reference

OPTIMIZER = "botorch-qlognehvi"
SEED_STREAM = 0xB07C  # separates the batches' seeds from every other use of the run's seed
MC_SAMPLES, RESTARTS, RAW_SAMPLES, MAX_ITER = 128, 10, 512, 200


def batch_seed(seed: int, rows: int) -> int:
    """Torch's seed for the batch after ``rows`` rows: (seed, rows) and nothing else."""
    return int(np.random.SeedSequence([seed, SEED_STREAM, rows]).generate_state(1)[0])


def reference_point(config: RunConfig, objectives: np.ndarray) -> np.ndarray:
    """(O,) the run's reference in the objectives (larger is better): the warm-up's worst value
    of each minus 10 % of its range (``mjxskill.training.front.hypervolume_reference``)."""
    return -hypervolume_reference(objectives[: config.n_init])


def tutorial_model(x, y):
    """BoTorch's tutorial model on inputs ``x`` (n, d) in the unit cube and outputs ``y`` (n, O),
    larger is better (torch tensors): one ``SingleTaskGP`` per objective, outputs standardized,
    fitted by marginal likelihood."""
    # lazy, here and below: an optional extra, imported only when this optimizer runs
    from botorch.fit import fit_gpytorch_mll
    from botorch.models import ModelListGP, SingleTaskGP
    from botorch.models.transforms import Standardize
    from gpytorch.mlls import SumMarginalLogLikelihood

    model = ModelListGP(*[SingleTaskGP(x, y[:, i : i + 1], outcome_transform=Standardize(m=1)) for i in range(y.shape[1])])
    fit_gpytorch_mll(SumMarginalLogLikelihood(model.likelihood, model))
    return model


def qlognehvi_batch(model, x, ref_point, q: int):
    """The tutorial's next ``q`` points (q, d) in the unit cube: qLogNEHVI about ``ref_point``
    (O,), larger is better, all of ``x`` the noisy baseline, optimized sequentially."""
    # lazy: an optional extra
    import torch
    from botorch.acquisition.multi_objective.logei import qLogNoisyExpectedHypervolumeImprovement
    from botorch.optim.optimize import optimize_acqf
    from botorch.sampling import SobolQMCNormalSampler

    acq = qLogNoisyExpectedHypervolumeImprovement(model=model, ref_point=list(ref_point), X_baseline=x,
                                                  prune_baseline=True,
                                                  sampler=SobolQMCNormalSampler(sample_shape=torch.Size([MC_SAMPLES])))
    d = x.shape[1]
    unit = torch.stack([torch.zeros(d), torch.ones(d)]).double()
    cand, _ = optimize_acqf(acq, bounds=unit, q=q, sequential=True, num_restarts=RESTARTS, raw_samples=RAW_SAMPLES,
                            options={"batch_limit": 5, "maxiter": MAX_ITER})
    return cand


@contextlib.contextmanager
def quiet():
    """BoTorch's notes on every jittered Cholesky factor and restarted L-BFGS-B held back: they
    change nothing here."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", module=r"(botorch|linear_operator|gpytorch)(\.|$)")
        yield


def ask(config: RunConfig, params: np.ndarray, objectives: np.ndarray, size: int) -> np.ndarray:
    """The next ``size`` parameter sets (size, P) after the rows ``params`` (n, P) and
    ``objectives`` (n, O, larger is better) so far."""
    # lazy: an optional extra (torch takes seconds to import); configure refuses the run without it
    import torch

    lo, hi = (np.asarray(b, np.float64) for b in config.bounds)
    params, objectives = np.asarray(params, np.float64), np.asarray(objectives, np.float64)
    ok = np.all(np.isfinite(objectives), axis=1)
    x = torch.from_numpy((params[ok] - lo) / (hi - lo))
    y = torch.from_numpy(objectives[ok])
    torch.manual_seed(batch_seed(config.seed, len(params)))
    with quiet():
        cand = qlognehvi_batch(tutorial_model(x, y), x, reference_point(config, objectives).tolist(), size)
    u = np.clip(cand.detach().numpy().astype(np.float64), 0.0, 1.0)
    return lo + u * (hi - lo)


__all__ = ["OPTIMIZER", "ask", "batch_seed", "qlognehvi_batch", "reference_point", "tutorial_model"]
