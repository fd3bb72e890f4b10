"""The run settings table (mjxskill/runs/settings.py): one check for the flags and for
config.yaml, and a table that agrees with RunConfig and with train's options."""

import argparse
import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from mjxskill.cli.args import setting_type
from mjxskill.cli.train import build_parser
from mjxskill.errors import RunError
from mjxskill.runs.run_config import RunConfig
from mjxskill.runs.settings import SETTINGS, Setting
from toy_runs import make_config

REPO = Path(__file__).resolve().parents[2]


def test_the_table_is_the_run_configuration_and_the_flags():
    fields = {f.name for f in dataclasses.fields(RunConfig)}
    assert {s.name for s in SETTINGS} <= fields  # each setting is a RunConfig field
    assert fields - {s.name for s in SETTINGS} == {"task", "scenario", "parameter_names", "parameter_units", "bounds",
                                                   "objective_names", "optimizer_options", "prior",
                                                   "optimizer_defaults", "cluster", "scenario_changes",
                                                   "engine_reason"}  # the rest: the plan's
    # (the prior: the scenario's or --prior-from's, mjxskill.training.priors; the generation of
    # gp's defaults the run began with; cluster: "ray" when made to run on a Ray cluster; the
    # scenario changes a resume accepted; why the engine, said by the header, not stored)
    options = {a.dest: a for a in build_parser()._actions}
    for s in SETTINGS:
        assert options[s.name].option_strings == [s.flag]


def test_a_run_made_for_a_ray_cluster_says_so_and_a_bad_value_is_refused():
    config = dataclasses.replace(make_config(repeats=1), cluster="ray")
    assert "cluster: ray" in config.to_yaml()
    assert RunConfig.from_yaml(config.to_yaml(), "run/config.yaml") == config
    older = yaml.safe_load(make_config(repeats=1).to_yaml())
    del older["cluster"]  # a config.yaml written before clusters: made on one machine
    assert RunConfig.from_yaml(yaml.safe_dump(older, sort_keys=False), "old/config.yaml").cluster is None
    with pytest.raises(RunError, match="cluster.*expected one of ray or null, got 'dask'"):
        RunConfig.from_yaml(config.to_yaml().replace("cluster: ray", "cluster: dask"), "run/config.yaml")


def test_a_setting_added_later_takes_its_default_in_an_older_config(tmp_path):
    config = make_config(repeats=1)
    data = yaml.safe_load(config.to_yaml())
    del data["repeats"]  # a config.yaml written before the setting existed
    assert RunConfig.from_yaml(yaml.safe_dump(data, sort_keys=False), "old/config.yaml") == config


def as_flag(setting: Setting, text: str):
    try:
        return "ok", setting_type(setting)(text)
    except argparse.ArgumentTypeError as err:
        return "error", str(err)


def as_config_entry(setting: Setting, text: str):
    data = yaml.safe_load(make_config().to_yaml())
    body = yaml.safe_dump({k: v for k, v in data.items() if k != setting.name}, sort_keys=False)
    try:
        config = RunConfig.from_yaml(body + f"{setting.name}: {text}\n", "run/config.yaml")
    except RunError as err:
        message = str(err)
        prefix = f"run/config.yaml: {setting.name} (line "
        assert message.startswith(prefix), message
        return "error", message.split("): ", 1)[1]
    return "ok", getattr(config, setting.name)


NUMERIC = [s for s in SETTINGS if s.kind != "text" and s.name not in ("n_init", "repeats", "budget")]
TEXTS = st.one_of(
    st.integers(-10, 10).map(str), st.integers(2**32 - 3, 2**32 + 3).map(str),
    st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6).map(repr),
    st.sampled_from(["1.0e+300", "-0.5", "0.0", "3600.0", "3600.5", "many", "7.5", "12"]),
)


@settings(max_examples=150, deadline=None)
@given(setting=st.sampled_from(NUMERIC), text=TEXTS)
def test_a_value_is_refused_by_the_flag_exactly_when_config_yaml_refuses_it(setting, text):
    # n_init, budget and repeats meet cross-setting checks in a whole file; the others stand alone
    flag, entry = as_flag(setting, text), as_config_entry(setting, text)
    assert flag[0] == entry[0], (setting.name, text, flag, entry)
    if flag[0] == "ok":
        assert flag[1] == entry[1]
    else:  # the same reason; the value is shown as each source holds it ('7.5' or 7.5)
        assert flag[1].split(", got ")[0] == entry[1].split(", got ")[0], (flag, entry)


@pytest.mark.parametrize("text, message", [
    ("0", "must be at least 1, got 0"), ("x", "expected an integer, got 'x'"), ("2.5", "expected an integer, got 2.5")])
def test_config_yaml_names_file_key_and_line(text, message):
    kind, got = as_config_entry(next(s for s in SETTINGS if s.name == "batch_size"), text)
    assert (kind, got) == ("error", message)


# -- optimizer options: gp's acquisition settings, from the flag and from config.yaml -------------
def option_as_flag(text: str):
    try:
        return "ok", dict(build_parser().parse_args(["push", "--optimizer-option", text]).optimizer_option)
    except SystemExit:  # argparse printed the error
        return "error", None


def options_as_config_entry(body: str, older: bool = False):
    """(kind, RunConfig or error) of a config.yaml with these optimizer_options; older: as
    written before the generation of the optimizer's defaults was recorded."""
    data = yaml.safe_load(make_config().to_yaml())
    dropped = ("optimizer_options", "optimizer_defaults") if older else ("optimizer_options",)
    text = yaml.safe_dump({k: v for k, v in data.items() if k not in dropped}, sort_keys=False)
    try:
        return "ok", RunConfig.from_yaml(text + f"optimizer_options:\n{body}", "run/config.yaml")
    except RunError as err:
        return "error", str(err)


def test_every_acquisition_setting_is_an_option_of_both_sources_typed_by_gp(capsys):
    from mjxskill.gp import AcquisitionSettings
    from mjxskill.runs.run_config import optimizer_config

    for f in dataclasses.fields(AcquisitionSettings):
        default = getattr(AcquisitionSettings(), f.name)
        kind, options = option_as_flag(f"{f.name}={default}")
        assert (kind, options) == ("ok", {f.name: default}), f.name
        kind, config = options_as_config_entry(f"  {f.name}: {default}\n")
        assert kind == "ok" and config.optimizer_options == {f.name: default}, (f.name, config)
    kind, config = options_as_config_entry("  model: scalarized\n  learning_rate: 5.0e-2\n  n_raw: 256\n")
    assert kind == "ok"
    assert optimizer_config(config).acquisition == AcquisitionSettings(model="scalarized", learning_rate=0.05, n_raw=256)
    assert option_as_flag("learning_rate=1") == ("ok", {"learning_rate": 1.0})  # typed as gp's float field


@pytest.mark.parametrize("body, where, message", [
    ("  n_rwa: 3\n", "optimizer_options.n_rwa", "unknown acquisition setting 'n_rwa'; valid settings: scalarization, alpha,"),
    ("  n_raw: 0\n", "optimizer_options.n_raw", "acquisition setting n_raw: expected a positive integer, got 0"),
    ("  model: single\n", "optimizer_options.model", "acquisition setting model: expected one of 'hybrid', "),
    ("  tau: -1.0\n", "optimizer_options.tau", "acquisition setting tau: must be > 0, got -1.0"),
    ("  n_raw: true\n", "optimizer_options.n_raw", "acquisition setting n_raw: expected an integer, got True"),
    ("  n_raw: 8\n  n_restarts: 9\n", "optimizer_options", "acquisition setting n_restarts (9) exceeds n_raw (8)"),
])
def test_a_bad_optimizer_option_is_refused_by_both_sources_naming_it(capsys, body, where, message):
    kind, error = options_as_config_entry(body)
    assert kind == "error" and error.startswith(f"run/config.yaml: {where} (line ") and message in error, error
    if "\n  " not in body.strip("\n"):  # one entry: the flag refuses it too, with gp's reason
        key, value = body.strip().split(": ")
        assert option_as_flag(f"{key}={value if value != 'true' else 'True'}")[0] == "error"
        assert message.split(", got ")[0] in capsys.readouterr().err  # the value as each source holds it


def test_the_optimizer_options_an_older_run_wrote_are_still_read():
    """Before the acquisition settings were one gp field, config.yaml held MOBOConfig's flat
    fields under optimizer_options; those are the same names, values and meanings."""
    from mjxskill.gp.settings import acquisition_defaults
    from mjxskill.runs.run_config import optimizer_config

    old = {"alpha": 0.1, "bucket": 32, "n_raw": 256, "n_restarts": 4, "n_opt_steps": 50, "fit_starts": 1,
           "fit_steps": 20, "per_element_fit_max_rows": 64, "fit_max_rows": 64, "model": "scalarized", "n_draws": 64,
           "ei": "moments", "tau": 0.01}
    kind, config = options_as_config_entry("".join(f"  {k}: {v}\n" for k, v in old.items()), older=True)
    assert kind == "ok", config
    # Relative to the defaults of their time (generation 1: Chebyshev, hybrid), not today's.
    assert optimizer_config(config).acquisition == dataclasses.replace(acquisition_defaults(1), **old)
    assert RunConfig.from_yaml(config.to_yaml(), "again/config.yaml") == config


def test_a_run_configuration_is_read_and_checked_without_jax():
    """select, --resume and the page read runs' config.yaml; that must not cost jax's import
    (the optimizer options are checked by gp's numpy side: MOBOConfig, Prior)."""
    config = "docs/experiments/push/optimizer/seed-0/config.yaml"
    code = ("import sys; from mjxskill.runs.run_config import RunConfig; "
            f"RunConfig.from_yaml(open({config!r}).read(), {config!r}); "
            "print(sorted(m for m in ('jax', 'jaxlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert out.stdout.strip() == "[]"
