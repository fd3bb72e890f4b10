"""Issue 33, must-hold 4: what would exhaust the machine is bounded and refused with one located
``error:`` line (exit 2) before anything is written: YAML nesting in every file read as YAML,
and every numeric flag and file value that sizes the work."""

import pytest

from cli_helpers import error_line, invoke, snapshot
from mjxskill.scenario.fields import MAX_DEPTH
from scenario_texts import shipped_text
from test_bad_input import push_run


def test_a_scenario_nested_thousands_deep_is_one_located_error(tmp_path, capsys):
    deep = tmp_path / "deep.yaml"
    deep.write_text(shipped_text("push") + "\nextra: " + "[" * 20_000 + "]" * 20_000 + "\n")
    for command in ("plan", "train"):
        code, err = invoke(capsys, command, deep, *(["--out", tmp_path / "run"] if command == "train" else []))
        error_line(code, err, command, str(deep), f"nest more than {MAX_DEPTH} deep", "(line ")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("command", ["train", "evaluate", "select"])
def test_a_prior_nested_thousands_deep_in_config_yaml_is_one_located_error(tmp_path, capsys, command):
    run = push_run(tmp_path / "run")
    config = run.path / "config.yaml"
    text = config.read_text()
    assert "\nprior: null\n" in text
    config.write_text(text.replace("\nprior: null\n", "\nprior: " + "{k: " * 5000 + "1" + "}" * 5000 + "\n"))
    before = snapshot(run.path)
    code, err = invoke(capsys, command, *(["push", "--resume"] if command == "train" else []), run.path)
    error_line(code, err, command, str(config), f"nest more than {MAX_DEPTH} deep")
    assert snapshot(run.path) == before


def test_nesting_up_to_the_bound_is_read(tmp_path):
    from mjxskill.scenario.fields import compose_text

    inside = MAX_DEPTH - 1  # the top-level mapping is one level
    root = compose_text("a: " + "[" * inside + "1" + "]" * inside, "ok.yaml")
    node = root.mapping(optional=("a",))["a"]
    for _ in range(inside - 1):
        (node,) = node.seq()
    assert node.seq()[0].scalar() == 1
