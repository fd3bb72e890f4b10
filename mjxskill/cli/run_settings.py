"""The run settings on the command line of ``train`` and ``experiment``: one flag per setting
and ``--optimizer-option``, handed to the library (``mjxskill.training.configure``) as plain
values, and what it refuses worded with the flags the user typed (``--init 10 exceeds the budget
of 6 evaluations``, ``--resume continues RUN with its own settings; drop --budget 9 (the run has
6)``)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

from mjxskill.cli import args as cli_args
from mjxskill.errors import CommandError, ResumeConflict, SettingError, quote
from mjxskill.runs.run_dir import Run, RunConfig
from mjxskill.runs.run_task import record_scenario_change, scenario_difference
from mjxskill.runs.settings import BY_NAME, SETTINGS, optimizer_option_value
from mjxskill.training.configure import new_run_config, resumed_run_config
from mjxskill.training.priors import describe_prior

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.scenario.schema import Scenario
    from mjxskill.task import PlannedTask


def add_setting_arguments(parser: argparse.ArgumentParser, skip: tuple[str, ...] = (), defaults: dict | None = None) -> None:
    """One flag per run setting but ``skip`` (the same checks as config.yaml's,
    mjxskill.runs.settings; ``defaults``: name -> the default's text for the help), and
    --quiet and --optimizer-option: the flags of every command that trains."""
    for setting in SETTINGS:
        if setting.name in skip:
            parser.set_defaults(**{setting.name: None})
            continue
        default = (defaults or {}).get(setting.name) or setting.default_text or (
            "the scenario's" if setting.scenario is not None else setting.default)
        parser.add_argument(setting.flag, dest=setting.name, type=cli_args.setting_type(setting),
                            help=f"{setting.help} (default: {default})")
    parser.add_argument("--quiet", action="store_true", help="no progress bar: one log line per batch")
    parser.add_argument("--optimizer-option", action="append", type=optimizer_option, metavar="KEY=VALUE", default=None,
                        help="an acquisition setting of mjxskill.gp (AcquisitionSettings), e.g. n_raw=256 or "
                             "model=scalarized (repeatable; stored with the run)")


def optimizer_option(text: str) -> tuple[str, int | float | str]:
    """``KEY=VALUE`` for an acquisition setting of mjxskill.gp (argparse type), VALUE typed and
    checked by gp (a number or one of the setting's choices). What several options must satisfy
    together is checked when the run's configuration is made (``new_config``)."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {quote(text)}")
    try:
        return key, optimizer_option_value(key, value)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _settings(args: argparse.Namespace) -> dict:
    """The run settings the flags give (a flag not given is None: the scenario's default)."""
    return {s.name: getattr(args, s.name) for s in SETTINGS}


def new_config(args: argparse.Namespace, scn: Scenario, task: PlannedTask,
               defaults: Mapping[str, object] | None = None) -> RunConfig:
    """The configuration of a new run of ``task``: the flags over ``defaults`` (the command's own,
    e.g. the experiment's repetitions) over the scenario's."""
    settings = _settings(args)
    settings.update({name: value for name, value in (defaults or {}).items() if settings[name] is None})
    try:
        return new_run_config(scn, task, args.task, settings, dict(args.optimizer_option or []),
                              getattr(args, "prior_from", None))
    except SettingError as err:
        if not err.given:  # the scenario's default: the library's words name it
            raise
        if err.name == "optimizer_options":
            raise CommandError(f"--optimizer-option: {err.problem}") from None
        raise CommandError(f"{BY_NAME[err.name].flag} {err.value} {err.problem}") from None


def resumed_config(args: argparse.Namespace, run_path: Path | None = None) -> RunConfig:
    """The configuration of the run ``--resume`` names (or ``run_path``, a run inside it),
    refusing flags that would change it."""
    try:
        config = resumed_run_config(run_path or args.resume, _settings(args), dict(args.optimizer_option or []),
                                    getattr(args, "prior_from", None))
    except ResumeConflict as err:
        name, given, own = err.conflicts[0]
        if name == "optimizer_options":
            raise CommandError(f"--resume continues {args.resume} with its own optimizer options {own}; "
                               "drop --optimizer-option") from None
        if name == "prior":
            raise CommandError(f"--resume continues {args.resume} with the prior it started with "
                               f"({describe_prior(own)}); drop --prior-from {given}") from None
        drop = ", ".join(f"{BY_NAME[name].flag} {given} (the run has {own})" for name, given, own in err.conflicts)
        raise CommandError(f"--resume continues {args.resume} with its own settings; drop {drop}") from None
    if args.out is not None and Path(args.out).resolve() != Path(args.resume).resolve():
        raise CommandError("--out and --resume name different directories; --resume writes into its own")
    return config


def add_accept_scenario_change(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--accept-scenario-change", action="store_true", dest="accept_scenario_change",
                        help="with --resume: continue although the scenario file differs from the run's copy "
                             "(scenario.yaml); the change is recorded in config.yaml and the old copy kept")


def accept_scenario(args: argparse.Namespace, run: Run, scn: Scenario) -> bool:
    """Refuses a resume whose scenario differs from the run's copy, naming the first difference,
    unless --accept-scenario-change; with it, records the change under ``args.resume``. Returns
    whether the run's files changed (its configuration must be read again)."""
    difference = scenario_difference(run, scn)
    if difference is None:
        return False
    if not args.accept_scenario_change:
        raise CommandError(f"{args.task} is not the scenario {args.resume} was trained with (its copy "
                           f"{difference.copy}): {difference.text()}; resume with the run's own scenario, or give "
                           "--accept-scenario-change to continue with this one (recorded in config.yaml)")
    record_scenario_change(args.resume, args.task, scn, difference)
    print(f"{args.resume} continues with the scenario {args.task} ({difference.text()}); recorded in config.yaml, "
          f"the previous copy kept", flush=True)
    return True
