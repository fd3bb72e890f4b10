"""Each repetition's pick, found where the protocol puts it: the race of a robust run's front
(``mjxskill.evaluation.racing``) or the validation of a paper-protocol run's contenders
(``mjxskill.evaluation.validation``), once the optimizer run is trained and evaluated."""

from __future__ import annotations

from mjxskill.errors import RunError
from mjxskill.evaluation.evaluate_run import evaluation_current, load_evaluation
from mjxskill.evaluation.pooled import pick
from mjxskill.evaluation.racing import load_race
from mjxskill.evaluation.validation import in_contention, load_validation
from mjxskill.experiment.directory import (
    Experiment,
    Protocol,
    is_done,
    repetition_race,
    repetition_settings,
    repetition_validation,
)
from mjxskill.runs.run_dir import RunConfig
from mjxskill.runs.run_task import load_run_task


def picked_repetition(exp: Experiment, config: RunConfig, protocol: Protocol, i: int):
    """(seed, the optimizer run's config, its front, its evaluation, its pick, the validation,
    the race) of repetition ``i`` once its optimizer run is trained, evaluated and picked; None
    before."""
    opt, _ = exp.runs(config)[i]
    seed = config.seed + i
    opt_config = opt.config()
    if not (is_done(opt, opt_config) and evaluation_current(opt, opt_config, repetition_settings(config, protocol, seed))):
        return None
    front = opt.front(opt_config)
    ev, _ = load_evaluation(opt)
    validation, raced = None, None
    race_of = repetition_race(config, protocol, seed, int(ev.known.sum()))
    if race_of is not None:
        raced = load_race(opt.path, front, race_of)
        if raced is None:
            return None
        chosen = pick(front, ev, protocol.max_force, source=protocol.max_force_source, race=raced)
        return seed, opt_config, front, ev, chosen, None, raced
    settings = repetition_validation(config, protocol, seed)
    if settings is not None:
        rows = in_contention(front, protocol.max_force, protocol.validation_candidates)
        validation = load_validation(opt, front, rows, settings)
        if validation is None:
            return None
    return seed, opt_config, front, ev, pick(front, ev, protocol.max_force, validation, protocol.max_force_source), validation, None


def repetition_pick(exp: Experiment, i: int) -> int | None:
    """The picked row of the front of repetition ``i`` (None: no solution within the bound);
    RunError before the repetition is picked."""
    picked = picked_repetition(exp, exp.config(), exp.protocol(), i)
    if picked is None:
        raise RunError(f"{exp.path}: repetition {i + 1} is not picked yet")
    return picked[4].row


def opt_task(exp: Experiment, config: RunConfig):
    """The planned task of the experiment's runs (for the operators' sets of the confirmation)."""
    return load_run_task(exp.optimizer, config)[1]




__all__ = ["opt_task", "picked_repetition", "repetition_pick"]
