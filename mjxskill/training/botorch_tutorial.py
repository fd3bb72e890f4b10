"""BoTorch's multi-objective tutorial, the model and the batch that ``botorch-qlognehvi``
proposes (``mjxskill.training.botorch_search``, which says what each is) and that
``benchmarks/mobo_quality.py`` runs on the held-out problems.

BoTorch, GPyTorch and PyTorch are imported here at the top: this module is the optional extra's
(``pip install 'mjxskill[botorch]'``), imported only when that optimizer proposes or the
benchmark runs it, so nothing else of mjxskill imports them.
"""

from __future__ import annotations

import contextlib
import warnings

import numpy as np
import torch
from botorch.acquisition.multi_objective.logei import qLogNoisyExpectedHypervolumeImprovement
from botorch.fit import fit_gpytorch_mll
from botorch.models import ModelListGP, SingleTaskGP
from botorch.models.transforms import Standardize
from botorch.optim.optimize import optimize_acqf
from botorch.sampling import SobolQMCNormalSampler
from gpytorch.mlls import SumMarginalLogLikelihood

MC_SAMPLES, RESTARTS, RAW_SAMPLES, MAX_ITER = 128, 10, 512, 200


def tutorial_model(x, y):
    """BoTorch's tutorial model on inputs ``x`` (n, d) in the unit cube and outputs ``y`` (n, O),
    larger is better (torch tensors): one ``SingleTaskGP`` per objective, outputs standardized,
    fitted by marginal likelihood."""
    model = ModelListGP(*[SingleTaskGP(x, y[:, i : i + 1], outcome_transform=Standardize(m=1)) for i in range(y.shape[1])])
    fit_gpytorch_mll(SumMarginalLogLikelihood(model.likelihood, model))
    return model


def qlognehvi_batch(model, x, ref_point, q: int):
    """The tutorial's next ``q`` points (q, d) in the unit cube: qLogNEHVI about ``ref_point``
    (O,), larger is better, all of ``x`` the noisy baseline, optimized sequentially."""
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


def next_batch(x: np.ndarray, y: np.ndarray, ref_point, q: int, seed: int) -> np.ndarray:
    """(q, d) float64: the tutorial's next ``q`` points in the unit cube after the rows ``x``
    (n, d; in the unit cube) and ``y`` (n, O; finite, larger is better), about ``ref_point`` (O,),
    torch's generator seeded with ``seed`` first."""
    xt, yt = torch.from_numpy(x), torch.from_numpy(y)
    torch.manual_seed(seed)
    with quiet():
        cand = qlognehvi_batch(tutorial_model(xt, yt), xt, ref_point, q)
    return cand.detach().numpy().astype(np.float64)


__all__ = ["MAX_ITER", "MC_SAMPLES", "RAW_SAMPLES", "RESTARTS", "next_batch", "qlognehvi_batch", "quiet",
           "tutorial_model"]
