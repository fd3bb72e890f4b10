"""Multi-objective Bayesian optimization in JAX: float64 Matern 5/2 GPs (one per objective by
default), log-EI on random scalarizations of their posterior draws (hypervolume
scalarizations by default, augmented Chebyshev as an option), sequential greedy batches
(Kriging believer).

``minimize(f, bounds, budget, ...)`` for a whole run; ``MOBOConfig(bounds, n_objectives,
batch_size, n_init, seed, acquisition=AcquisitionSettings(...))`` and ``init``/``ask``/``tell`` and
``save_state``/``load_state`` for a run that stops and resumes (``tell(..., noise=...)`` and
``observed`` for rows with a known noise variance, e.g. means over several evaluations); ``Prior(mean, std, weights)``
(``MOBOConfig(prior=...)``, ``minimize(..., prior=...)``) for where good values are believed to
lie: it shapes the warm-up and weights the acquisition (piBO); ``pareto_mask`` and
``hypervolume`` to read the result. Objectives are minimized.

The GP computes in float64 inside local ``jax.enable_x64(True)`` scopes; importing this
package does not change ``jax_enable_x64`` for the rest of the process. The names above load
lazily (as ``mjxskill.engine.mjx``'s): importing the package imports no jax, and
``pareto_mask``, ``hypervolume`` and the settings (``mjxskill.gp.pareto``, ``mjxskill.gp.settings``)
never do.
"""

from typing import TYPE_CHECKING

from mjxskill._lazy import lazy_getattr

if TYPE_CHECKING:  # what __getattr__ below gives, for the type checker
    from mjxskill.gp.config import MOBOConfig
    from mjxskill.gp.optimizer import (
        MOBOResult,
        MOBOState,
        ask,
        init,
        load_state,
        minimize,
        observed,
        save_state,
        tell,
    )
    from mjxskill.gp.pareto import hypervolume, pareto_mask
    from mjxskill.gp.prior import Prior
    from mjxskill.gp.settings import AcquisitionSettings, acquisition_settings

_EXPORTS = {
    "MOBOConfig": "mjxskill.gp.config",  # numpy only: a run's configuration is checked without jax
    **dict.fromkeys(("MOBOResult", "MOBOState", "ask", "init", "load_state", "minimize", "observed",
                     "save_state", "tell"), "mjxskill.gp.optimizer"),
    **dict.fromkeys(("hypervolume", "pareto_mask"), "mjxskill.gp.pareto"),
    "Prior": "mjxskill.gp.prior",
    **dict.fromkeys(("AcquisitionSettings", "acquisition_settings"), "mjxskill.gp.settings"),
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_getattr(__name__, _EXPORTS)
