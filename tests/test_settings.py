"""The run settings table (mjxskill/training/settings.py): one check for the flags and for
config.yaml, and a table that agrees with RunConfig and with train's options."""

import argparse
import dataclasses

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from mjxskill.cli.args import setting_type
from mjxskill.cli.train import build_parser
from mjxskill.errors import RunError
from mjxskill.training.run_config import RunConfig
from mjxskill.training.settings import SETTINGS, Setting
from test_run_dir import make_config


def test_the_table_is_the_run_configuration_and_the_flags():
    fields = {f.name for f in dataclasses.fields(RunConfig)}
    assert {s.name for s in SETTINGS} <= fields  # each setting is a RunConfig field
    assert fields - {s.name for s in SETTINGS} == {"task", "scenario", "parameter_names", "parameter_units", "bounds",
                                                   "objective_names", "optimizer_options"}  # the rest: the plan's
    options = {a.dest: a for a in build_parser()._actions}
    for s in SETTINGS:
        assert options[s.name].option_strings == [s.flag]


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
