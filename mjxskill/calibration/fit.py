"""The fit: the scenario's declared physical values fitted to recordings with ``mujoco.sysid``.

``calibrate`` hands sysid what it asks for: the parameters with their ``MjSpec`` modifiers
(``mjxskill.calibration.twin``), the recordings as one ``ModelSequences`` (the scenario's spec,
each recording's start state, its measured torques as the control signal the report shows, its
measured signals over its window), a residual built by ``sysid.build_residual_fn`` whose rollout
and residual are the closed-loop replay (``mjxskill.calibration.replay``), ``sysid.optimize``
(scipy's trust-region least squares with MuJoCo's finite differences, ``scipy_parallel_fd``)
and ``sysid.calculate_intervals``. Three things are this module's own, each because the replay
is chaotic at small scales (a change of 1 g in the mass moves the joints by about 3e-4 rad; a
change of 1 mg does not):

1. **Finite-difference steps of a few percent.** The optimizer's step of each parameter is
   ``STEP_SHARE`` of its bounds' width, not the default 1.5e-8: a tiny step measures the chaos,
   not the slope; a step of a few percent of the range is a secant over it.
2. **Weights from the first round's errors.** The first round weighs each signal by its sensor's
   noise (``calibration.noise``). The twin cannot follow a recording closer than its own chaos,
   which for the joint angles is seven times their noise (0.35 against 0.05 mrad on the "true"
   twin's pushes), so each signal is then weighed by the larger of its noise and its RMS error at
   the first round's values (feasible generalized least squares), so that no signal's chaos
   drowns the others.
3. **Last Gauss-Newton steps on central secants.** sysid's trust region closes where the chaos
   hides the remaining slope (on the "true" twin: 4.5 and 12.5 % off in mass, along the valley
   where only mass times friction is well seen). From there Gauss-Newton steps are taken with
   the Jacobian of central differences over +-``SECANT_SHARE`` of each range, where the slope
   stands out of the chaos, each kept only when it lowers the residual, at most ``GN_STEPS``
   (``docs/calibration.md``: the errors they left).

**The intervals.** ``sysid.calculate_intervals`` takes the residual's samples as independent
with one variance. They are not: the replay's chaos and the sensors' noise run through a whole
window, and on ten recordings of the "true" twin its 95 % intervals were 30-60 times narrower
than the errors of the fit. The intervals written into the scenario are the cluster-robust
("sandwich") ones with each recording a cluster: the covariance (J'J)^-1 (sum_k J_k' r_k r_k'
J_k) (J'J)^-1 K/(K-1) of the secant Jacobian J and the residual r, with Student's t of K - 1
degrees of freedom for K recordings; they assume only that the recordings are independent of
each other. The toolbox's, from the same J and r, are reported beside them.
"""

from __future__ import annotations

import contextlib
import io
import logging
import time
from dataclasses import dataclass, field

import numpy as np
from mujoco import sysid
from scipy import stats

from mjxskill.calibration.recording import Recording
from mjxskill.calibration.replay import SIGNALS, Replay, Replayer, prepare
from mjxskill.calibration.twin import finite_difference_steps, sysid_parameters
from mjxskill.errors import ScenarioError, UserError
from mjxskill.scenario.calibration import CalibrationParameter, outside
from mjxskill.scenario.schema import Scenario
from mjxskill.sim.model import scenario_spec
from mjxskill.task import PlannedTask

STEP_SHARE = 0.03  # of a parameter's bounds' width: the optimizer's finite-difference step
SECANT_SHARE = 0.06  # of its width: the central secants of the last steps and the intervals
GN_STEPS = 3  # Gauss-Newton steps on them at most
MIN_RECORDINGS = 2  # the intervals come from how the recordings differ


@dataclass
class FitResult:
    """What a fit found: per parameter (in ``parameters``' order) the ``nominal`` and fitted
    ``values``, the half widths of the ``confidence`` intervals (``half_width``: cluster-robust,
    written into the scenario; ``toolbox_half_width``: sysid's), the ``cost`` (sum of squared
    residuals, with the final weights) with the nominal and the fitted values, the RMS error of
    each signal per recording before and after (``rms``: path -> {signal: (before, after)}), and
    what the report needs (``sysid``)."""

    parameters: tuple[CalibrationParameter, ...]
    nominal: np.ndarray
    values: np.ndarray
    half_width: np.ndarray
    toolbox_half_width: np.ndarray
    covariance: np.ndarray
    confidence: float
    cost: tuple[float, float]
    samples: int
    rms: dict
    seconds: float
    evaluations: int
    episodes: int
    message: str
    log: str
    sysid: dict = field(repr=False, default_factory=dict)

    @property
    def low(self) -> np.ndarray:
        return self.values - self.half_width

    @property
    def high(self) -> np.ndarray:
        return self.values + self.half_width


def _cached_build(limit: int = 16):
    """sysid's ``build_model`` (``apply_param_modifiers``), remembering the last ``limit``
    models by their values: sysid builds the model once per recording, the same values each."""
    built: dict[tuple, object] = {}

    def build(params, spec):
        key = tuple(np.round(params.as_vector(), 15))
        if key not in built:
            if len(built) >= limit:
                built.pop(next(iter(built)))
            built[key] = sysid.apply_param_modifiers(params, spec)
        return built[key]
    return build


def sandwich(residuals: list[np.ndarray], jac: np.ndarray, confidence: float) -> tuple[np.ndarray, np.ndarray]:
    """(covariance (p, p), half widths (p,)) of the cluster-robust intervals, each residual
    array of ``residuals`` a cluster whose rows of ``jac`` follow each other (module docstring)."""
    bread = np.linalg.pinv(jac.T @ jac)
    meat = np.zeros_like(bread)
    start = 0
    for r in residuals:
        score = jac[start:start + r.size].T @ r.ravel()
        meat += np.outer(score, score)
        start += r.size
    k = len(residuals)
    covariance = bread @ meat @ bread * k / (k - 1)
    half = stats.t.ppf(0.5 + confidence / 2, k - 1) * np.sqrt(np.maximum(np.diag(covariance), 0.0))
    return covariance, half


def _rms(replays: list[Replay], preds, records) -> dict:
    """recording -> signal -> RMS of recorded minus simulated over the window, in its unit."""
    out = {}
    for replay, pred, record in zip(replays, preds, records):
        error = record[0].data - pred[0].data
        column = {c: k for k, c in enumerate(replay.columns)}
        out[replay.recording.path] = {
            name: float(np.sqrt(np.mean(error[:, [column[c] for c in columns]] ** 2)))
            for name, columns in SIGNALS.items() if columns[0] in column}
    return out


def _reweigh(replays: list[Replay], rms: dict) -> dict[str, float]:
    """Each signal weighed, from now on, by the larger of its noise and its RMS error over all
    recordings (point 2 of the module docstring); returns signal -> that RMS."""
    pooled = {}
    for name in SIGNALS:
        errors = [rms[r.recording.path][name] for r in replays if name in rms[r.recording.path]]
        if errors:
            pooled[name] = float(np.sqrt(np.mean(np.square(errors))))
    for replay in replays:
        sd = replay.sd.copy()
        for name, columns in SIGNALS.items():
            index = [replay.columns.index(c) for c in columns if c in replay.columns]
            if index:
                sd[index] = np.maximum(sd[index], pooled[name])
        replay.sd = sd
    return pooled


def _whitened(replays: list[Replay], preds, records) -> list[np.ndarray]:
    """The residuals of simulated ``preds`` against ``records`` with the replays' present weights."""
    return [((m[0].data - p[0].data) / r.sd).ravel() for r, p, m in zip(replays, preds, records)]


class _Problem:
    """sysid's pieces of one fit: the parameters, the recordings as ``ModelSequences``, the residual."""

    def __init__(self, scn: Scenario, task: PlannedTask, recordings: list[Recording]):
        spec = scenario_spec(scn)
        self.replays = prepare(scn, task, recordings, spec.compile())
        self.params = sysid_parameters(scn, spec)
        self.sequences = sysid.ModelSequences(
            scn.name, spec, [r.recording.path for r in self.replays], [r.initial_state for r in self.replays],
            [_control(r) for r in self.replays], [r.measured for r in self.replays], allow_missing_sensors=True)
        self.replayer = Replayer(scn, task, self.replays)
        self.build = _cached_build()
        self.residual_fn = sysid.build_residual_fn(
            models_sequences=[self.sequences], build_model=self.build, custom_rollout=self.replayer.custom_rollout,
            modify_residual=self.replayer.modify_residual, resample_true=False, n_threads=1)

    def residuals(self, x: np.ndarray) -> list[np.ndarray]:
        return list(self.residual_fn(np.asarray(x, float), self.params)[0])

    def optimize(self, steps: np.ndarray, evaluations: int, log: io.StringIO):
        lower, upper = self.params.get_bounds()
        with contextlib.redirect_stdout(log):  # scipy's iteration table: kept for the report
            return sysid.optimize(self.params, self.residual_fn, optimizer="scipy_parallel_fd", verbose=False,
                                  max_iters=evaluations, diff_step=steps, x_scale=upper - lower)

    def secant_jacobian(self, x: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """(n residuals, p) central differences over +-``steps``, kept inside the bounds."""
        lower, upper = self.params.get_bounds()
        columns = []
        for j, h in enumerate(steps):
            hi, lo = x.copy(), x.copy()
            hi[j], lo[j] = min(x[j] + h, upper[j]), max(x[j] - h, lower[j])
            columns.append((np.concatenate(self.residuals(hi)) - np.concatenate(self.residuals(lo))) / (hi[j] - lo[j]))
        return np.array(columns).T


def _gauss_newton(problem: _Problem, x: np.ndarray, secants: np.ndarray, confidence: float, log: io.StringIO):
    """Point 3 of the module docstring: Gauss-Newton steps on central secants from ``x``, each
    kept only when it lowers the residual, until one moves every value by less than a quarter of
    its interval or ``GN_STEPS`` are taken. Returns (the point, the secant Jacobian there)."""
    lower, upper = problem.params.get_bounds()
    residuals = problem.residuals(x)
    cost = float(sum(np.sum(r ** 2) for r in residuals))
    jac = problem.secant_jacobian(x, secants)
    for _ in range(GN_STEPS):
        r = np.concatenate(residuals)
        moved = np.clip(x - np.linalg.pinv(jac.T @ jac) @ (jac.T @ r), lower, upper)
        trial = problem.residuals(moved)
        trial_cost = float(sum(np.sum(t ** 2) for t in trial))
        kept = trial_cost < cost
        log.write(f"Gauss-Newton step on central secants: {np.array2string(x, precision=5)} -> "
                  f"{np.array2string(moved, precision=5)}, residual {cost:.5g} -> {trial_cost:.5g}"
                  f"{'' if kept else ' (not kept)'}\n")
        if not kept:
            break
        small = np.all(np.abs(moved - x) < sandwich(residuals, jac, confidence)[1] / 4)
        x, residuals, cost = moved, trial, trial_cost
        if small:
            break
        jac = problem.secant_jacobian(x, secants)
    return x, jac


def calibrate(scn: Scenario, task: PlannedTask, recordings: list[Recording], *, max_evaluations: int = 40,
              confidence: float = 0.95, step_share: float = STEP_SHARE, secant_share: float = SECANT_SHARE) -> FitResult:
    """Fits ``scn``'s ``calibration.parameters`` to ``recordings`` of ``task`` (module docstring):
    sysid's optimizer (at most ``max_evaluations`` residual evaluations) from the YAML's values,
    the weights from its errors, Gauss-Newton steps on central secants, the intervals there.
    UserError when there are too few recordings, RecordingError when one holds no free push."""
    if scn.calibration is None:
        raise UserError(f"{scn.source}: the scenario declares no calibration section: nothing to fit")
    refused = outside(scn.calibration)
    if refused is not None:
        raise ScenarioError(refused)
    if len(recordings) < MIN_RECORDINGS:
        raise UserError(f"{len(recordings)} recording(s): the fit needs at least {MIN_RECORDINGS} (its intervals come "
                        "from how the recordings differ; docs/calibration.md: ten)")
    started = time.perf_counter()
    absl = logging.getLogger("absl")  # sysid's absl logging: it warns of every custom signal it does not simulate
    level = absl.level
    absl.setLevel(logging.ERROR)
    log = io.StringIO()
    try:
        problem = _Problem(scn, task, recordings)
        params, residual_fn = problem.params, problem.residual_fn
        _, preds0, records0 = residual_fn(params.as_vector(), params, return_pred_all=True)
        first, result = problem.optimize(finite_difference_steps(scn.calibration.parameters, step_share),
                                         max_evaluations, log)
        _, preds, records = residual_fn(first.as_vector(), first, return_pred_all=True)
        pooled = _reweigh(problem.replays, _rms(problem.replays, preds, records))
        log.write("weights from here (RMS error at these values): " + ", ".join(f"{k} {v:.3g}" for k, v in pooled.items()) + "\n")
        secants = finite_difference_steps(scn.calibration.parameters, secant_share).ravel()
        x, jac = _gauss_newton(problem, first.as_vector(), secants, confidence, log)
        fitted = first.copy()
        fitted.update_from_vector(x)
        after, preds1, records1 = residual_fn(fitted.as_vector(), fitted, return_pred_all=True)
    finally:
        absl.setLevel(level)
    result.jac = jac  # sysid's report computes its intervals from the result's Jacobian: the secants
    toolbox_cov, toolbox_half = sysid.calculate_intervals(after, jac, alpha=1 - confidence)
    covariance, half = sandwich(after, jac, confidence)
    replays = problem.replays
    rms0, rms1 = _rms(replays, preds0, records0), _rms(replays, preds1, records1)
    before = _whitened(replays, preds0, records0)
    return FitResult(
        parameters=scn.calibration.parameters, nominal=params.as_nominal_vector(), values=fitted.as_vector(),
        half_width=half, toolbox_half_width=np.asarray(toolbox_half, float), covariance=covariance,
        confidence=confidence,
        cost=(float(sum(np.sum(r ** 2) for r in before)), float(sum(np.sum(r ** 2) for r in after))),
        samples=int(sum(r.size for r in after)),
        rms={path: {s: (rms0[path][s], rms1[path][s]) for s in rms0[path]} for path in rms0},
        seconds=time.perf_counter() - started, evaluations=problem.replayer.episodes // max(1, len(replays)),
        episodes=problem.replayer.episodes, message=str(getattr(result, "message", "")), log=log.getvalue(),
        sysid={"sequences": problem.sequences, "initial": params, "fitted": fitted, "residual_fn": residual_fn,
               "result": result, "build_model": problem.build, "replays": replays, "toolbox_covariance": toolbox_cov,
               "predicted": (preds0, preds1), "measured": records1},
    )


def _control(replay: Replay):
    """The control signal sysid keeps with a recording: its measured joint torques (the report
    shows them), or zeros when the robot gave none; the replay computes its own."""
    rec = replay.recording
    torque = rec.joint_torque if rec.joint_torque is not None else np.zeros((len(rec.time), 7))
    return sysid.TimeSeries(np.asarray(rec.time, float), np.asarray(torque, float))


__all__ = ["FitResult", "GN_STEPS", "MIN_RECORDINGS", "SECANT_SHARE", "STEP_SHARE", "calibrate", "sandwich"]
