"""A run's configuration from plain values: a new run's (``new_run_config``) and a resumed run's
(``resumed_run_config``), what ``train`` and ``experiment`` build from their flags and a library
user builds without argparse.

The values are a mapping ``setting name -> value`` over the run settings of
``mjxskill.runs.settings`` (a missing name or None: the scenario's default), the optimizer options
(``mjxskill.gp`` acquisition settings), and the run whose Pareto front makes the prior
(``mjxskill.training.priors``). Each value goes through the check ``config.yaml`` goes through.
A value refused is a ``SettingError`` (a new run) or a ``ResumeConflict`` (a resumed run that has
other values): ``RunError`` kinds that carry the setting's name and value, so that a caller words
the message its own way (the command line names the flag the value came from).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Mapping

from mjxskill.engine.build import resolve_engine
from mjxskill.errors import PlanError, ResumeConflict, RunError, SettingError, quote
from mjxskill.runs.run_config import optimizer_problem
from mjxskill.runs.run_dir import Run, RunConfig
from mjxskill.runs.settings import BY_NAME, SETTINGS, cross_problems, optimizer_option_value
from mjxskill.runs.training_protocol import objective_names
from mjxskill.training.extras import missing_extra
from mjxskill.training.priors import describe_prior, prior_from_run, run_prior

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario.schema import Scenario
    from mjxskill.task import PlannedTask


def stored_scenario(scenario: str) -> str:
    """What a run stores as its scenario: a scenario name stays a name; a YAML path is made
    absolute (evaluate and select load it from anywhere)."""
    if Path(scenario).name == scenario and not scenario.endswith((".yaml", ".yml")):
        return scenario
    return str(Path(scenario).resolve())


def _given(settings: Mapping[str, object]) -> dict:
    """The settings given (None: not given), each checked as config.yaml's."""
    unknown = sorted(set(settings) - set(BY_NAME))
    if unknown:
        raise ValueError(f"unknown run settings {', '.join(unknown)}; the settings are {', '.join(BY_NAME)}")
    given = {}
    for name, value in settings.items():
        if value is None:
            continue
        try:
            given[name] = BY_NAME[name].coerce(value)
        except ValueError as err:
            raise SettingError(f"{name}: {err}", name=name, value=value, given=True, problem=str(err)) from None
    return given


def _options(optimizer_options: Mapping[str, object] | None) -> dict:
    """The optimizer options given, each typed and checked by gp."""
    options = {}
    for key, value in dict(optimizer_options or {}).items():
        try:
            options[key] = optimizer_option_value(key, value)
        except ValueError as err:
            # the loop ran: options were given
            raise SettingError(f"optimizer_options: {err}", name="optimizer_options", value=dict(optimizer_options),  # type: ignore[arg-type]
                               given=True, problem=str(err)) from None
    return options


def new_run_config(scn: Scenario, task: PlannedTask, scenario: str, settings: Mapping[str, object] | None = None,
                   optimizer_options: Mapping[str, object] | None = None,
                   prior_from: Path | str | None = None) -> RunConfig:
    """The configuration of a new run of ``task`` (planned in ``scn``, loaded from ``scenario``,
    a scenario name or a YAML path): ``settings`` over the scenario's defaults, the engine
    ``auto`` resolved (and why, ``engine_reason``), ``optimizer_options``, and the prior of the
    run ``prior_from`` (over the scenario's ``parameter_priors``). Raises SettingError for a value the run cannot take, and
    the RunError of ``prior_from_run`` for a run that cannot give a prior."""
    given = _given(settings or {})
    options = _options(optimizer_options)
    values = {s.name: given[s.name] if s.name in given else s.default_for(scn) for s in SETTINGS}
    values["goal"] = task.goal
    values["engine"], engine_reason = resolve_engine(values["engine"])  # resolved once: the header says why
    problem: str | None
    for name, problem in cross_problems(values):
        origin = f"{name} {values[name]}" + ("" if name in given else " (the scenario's default)")
        raise SettingError(f"{origin} {problem}", name=name, value=values[name], given=name in given, problem=problem)
    absent = missing_extra(values["optimizer"])  # before the run directory is made
    if absent:
        raise SettingError(f"optimizer {values['optimizer']} {absent}", name="optimizer", value=values["optimizer"],
                           given=True, problem=absent)
    config = RunConfig(
        task=scn.name,
        scenario=stored_scenario(scenario),
        parameter_names=tuple(task.parameter_names),
        parameter_units=tuple(task.parameter_units),
        bounds=(tuple(map(float, task.bounds[0])), tuple(map(float, task.bounds[1]))),
        objective_names=objective_names(scn.objective_names, values["protocol"]),
        optimizer_options=options,
        prior=run_prior(scn, task, prior_from),
        engine_reason=engine_reason,
        **values,
    )
    if not config.parameter_names:
        raise PlanError(f"the plan for {quote(config.goal)} leaves no parameter to learn")
    problem = optimizer_problem(config)  # the run's own settings are checked: an option is left
    if problem:
        raise SettingError(f"optimizer_options: {problem}" if options else f"the optimizer refuses this run: {problem}",
                           name="optimizer_options", value=options, given=bool(options), problem=problem)
    return config


def resumed_run_config(path: Path | str, settings: Mapping[str, object] | None = None,
                       optimizer_options: Mapping[str, object] | None = None,
                       prior_from: Path | str | None = None) -> RunConfig:
    """The configuration of the run in ``path``, to resume it. The values given (as
    ``new_run_config`` takes them; none: the run's own) must be the run's own: a ResumeConflict
    names those that are not, the optimizer options first, then the settings (all of them), then
    the prior."""
    run = Run(path)
    config = run.config()
    given = _given(settings or {})
    options = _options(optimizer_options)
    if options and options != config.optimizer_options:
        raise ResumeConflict(f"{run.path} continues with its own optimizer options {config.optimizer_options}, not "
                             f"{options}", run=run.path,
                             conflicts=(("optimizer_options", options, config.optimizer_options),))
    conflicts = tuple((s.name, given[s.name], getattr(config, s.name)) for s in SETTINGS
                      if s.name in given and given[s.name] != getattr(config, s.name))
    if conflicts:
        raise ResumeConflict(f"{run.path} continues with its own settings: "
                             + ", ".join(f"{name} {value} given, the run has {own}" for name, value, own in conflicts),
                             run=run.path, conflicts=conflicts)
    if prior_from is not None:
        prior = prior_from_run(prior_from, config.parameter_names, config.bounds)
        stored = None if config.prior is None else {k: v for k, v in config.prior.items() if k != "source"}
        if stored != {k: v for k, v in prior.items() if k != "source"}:
            raise ResumeConflict(f"{run.path} continues with the prior it started with ({describe_prior(config.prior)}), "
                                 f"not the one of the run {prior_from}", run=run.path,
                                 conflicts=(("prior", prior_from, config.prior),))
    absent = missing_extra(config.optimizer)
    if absent:
        raise RunError(f"{run.path} trains with the optimizer {config.optimizer}, which {absent}")
    return config


__all__ = ["new_run_config", "resumed_run_config", "stored_scenario"]
