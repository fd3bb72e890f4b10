"""A toy run: two parameters and two objectives with no scenario behind them. Its configuration
(``make_config``), its run directory (``make_run``, ``new_run``), random evaluation rows
(``rows``), and for the training loop a closed-form objective in place of the physics
(``toy_objective``, ``Recorder``) with the configuration the loop's tests train (``CONFIG``)."""

import numpy as np

from mjxskill.runs.run_dir import EVALUATIONS, Evaluations, Run, RunConfig, read_csv
from mjxskill.training.loop import BatchResult


def make_config(**changes) -> RunConfig:
    base = dict(task="toy", scenario="toy", goal="(at a b)", parameter_names=("S.x", "S.y"), parameter_units=("m", "N"),
                bounds=((0.0, -1.0), (1.0, 1.0)), objective_names=("reach", "force"), budget=10, batch_size=4,
                n_init=6, worlds=2, seed=0, episode_seconds=0.5)
    base.update(changes)
    return RunConfig(**base)


def make_run(tmp_path, config=None) -> Run:
    src = tmp_path / "scenario-source.yaml"
    src.write_text("name: toy\n")
    run = Run(tmp_path / "run")
    run.create(config or make_config(), str(src), {"plan.txt": "(a)"})
    return run


def rows(iterations, p=2, o=2, seed=0) -> Evaluations:
    rng = np.random.default_rng(seed)
    n = len(iterations)
    return Evaluations(np.asarray(iterations), rng.random((n, p)), rng.normal(size=(n, o)), rng.random(n),
                       rng.random(n) * 30, rng.random(n) * 10, rng.random(n) * 7)


# A cheap acquisition search: these tests pin the loop's bookkeeping, not the GP's quality.
QUICK_GP = dict(n_raw=64, n_restarts=2, n_opt_steps=10, fit_starts=1, fit_steps=10)
CONFIG = make_config(budget=10, batch_size=4, n_init=6, seed=2, optimizer_options=QUICK_GP)  # batches of 4, 2, 4


def toy_objective(x: np.ndarray, iteration: int) -> BatchResult:
    """Two conflicting closed-form objectives (larger is better); depends on the batch index
    the way the real rollout's worlds do."""
    reach = -(x[:, 0] - 0.3) ** 2 - 0.01 * iteration
    force = -np.abs(x[:, 1]) - x[:, 0]
    return BatchResult(np.stack([reach, force], axis=1), (x[:, 0] > 0.5).astype(float), 10 * x[:, 0], 3 * x[:, 0], 7 + 0 * x[:, 0])


class Recorder:
    """The toy objective, recording each call and how many rows were on disk at that moment;
    ``stop_after`` batches raises KeyboardInterrupt (a Ctrl-C during the next batch)."""

    def __init__(self, run=None, stop_after=None):
        self.run, self.stop_after = run, stop_after
        self.calls, self.rows_on_disk = [], []

    def __call__(self, x, iteration):
        if self.stop_after is not None and len(self.calls) == self.stop_after:
            raise KeyboardInterrupt
        self.calls.append((iteration, x.copy()))
        if self.run is not None:
            self.rows_on_disk.append(len(read_csv(self.run.path / EVALUATIONS, CONFIG.columns())))
        return toy_objective(x, iteration)


def new_run(tmp_path, name, config=CONFIG):
    src = tmp_path / "src.yaml"
    src.write_text("name: toy\n")
    run = Run(tmp_path / name)
    run.create(config, str(src), {})
    return run
