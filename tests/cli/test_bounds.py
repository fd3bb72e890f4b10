"""What would exhaust the machine is bounded and refused with one located
``error:`` line (exit 2) before anything is written: YAML nesting in every file read as YAML,
and every numeric flag and file value that sizes the work."""

import pytest

from cli_helpers import error_line, invoke, snapshot
from mjxskill.scenario.fields import MAX_DEPTH
from scenario_texts import shipped_text
from push_runs import push_run


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


# -- numbers that size the work --------------------------------------------------------------------
TRAIN_FLAGS = [  # (flags, what the error line says)
    (["--budget", "1000000000000"], "argument --budget: must be at most 100000, got 1000000000000"),
    (["--batch-size", "1000000000"], "argument --batch-size: must be at most 4096, got 1000000000"),
    (["--worlds", "100000"], "argument --worlds: must be at most 4096, got 100000"),
    (["--repeats", "100000"], "argument --repeats: must be at most 1000, got 100000"),
    (["--episode-seconds", "1e9"], "must be at most 3600 s"),
    (["--batch-size", "4096", "--worlds", "4096", "--budget", "8192"], "more than 262144"),
]


@pytest.mark.parametrize("command", ["train", "experiment"])
@pytest.mark.parametrize("flags, message", TRAIN_FLAGS)
def test_run_settings_over_their_bound_are_refused_before_a_directory_is_made(tmp_path, capsys, command, flags, message):
    out = tmp_path / "out"
    code, err = invoke(capsys, command, "push", *flags, "--out", out)
    error_line(code, err, command, message)
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command, flags, message", [
    ("experiment", ["--per-config", "100000"], "--per-config: must be at most 1000"),
    ("experiment", ["--random", "1000000000"], "--random: must be at most 10000"),
    ("experiment", ["--validation-candidates", "1000"], "--validation-candidates: must be at most 100"),
    ("experiment", ["--validation-per-config", "5000"], "--validation-per-config: must be at most 1000"),
])
def test_evaluation_numbers_over_their_bound_are_refused(tmp_path, capsys, command, flags, message):
    out = tmp_path / "out"
    code, err = invoke(capsys, command, "push", *flags, "--out", out)
    assert code == 2 and message in err and "Traceback" not in err, err
    assert not out.exists()


@pytest.mark.parametrize("command, flags, message", [
    ("evaluate", ["--random", "1000000000"], "--random: must be at most 10000"),
    ("evaluate", ["--per-config", "100000"], "--per-config: must be at most 1000"),
    ("evaluate", ["--batch-size", "1000000000"], "--batch-size: must be at most 4096"),
    ("explore", ["--per-config", "100000"], "--per-config: must be at most 1000"),
    ("select", ["--size", "100000", "100000"], "--size: must be at most 8192"),
])
def test_flags_of_commands_on_a_run_are_bounded(tmp_path, capsys, command, flags, message):
    run = push_run(tmp_path / "run")
    before = snapshot(run.path)
    code, err = invoke(capsys, command, run.path, *flags)
    assert code == 2 and message in err and "Traceback" not in err, err
    assert snapshot(run.path) == before


@pytest.mark.parametrize("old, new, key, message", [
    ("  budget: 400\n", "  budget: 1000000000000\n", "optimizer.budget", "expected an integer <= 100000"),
    ("  batch_size: 6\n", "  batch_size: 1000000000\n", "optimizer.batch_size", "expected an integer <= 4096"),
    ("  n_worlds: 7\n", "  n_worlds: 100000\n", "randomization.n_worlds", "expected an integer <= 4096"),
    ("  repetitions: 10\n", "  repetitions: 100000\n", "optimizer.repetitions", "expected an integer <= 1000"),
])
def test_scenario_values_over_their_bound_are_one_located_error(tmp_path, capsys, old, new, key, message):
    text = shipped_text("push")
    assert text.count(old) == 1
    path = tmp_path / "big.yaml"
    path.write_text(text.replace(old, new))
    code, err = invoke(capsys, "train", path, "--out", tmp_path / "run")
    error_line(code, err, "train", f"{path}: {key} (line ", message)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("key, value, message", [
    ("budget", 1_000_000, "must be at most 100000"),
    ("worlds", 100_000, "must be at most 4096"),
    ("batch_size", 10**9, "must be at most 4096"),
    ("repeats", 100_000, "must be at most 1000"),
])
@pytest.mark.parametrize("command", ["train", "evaluate", "select"])
def test_config_yaml_values_over_their_bound_are_one_located_error(tmp_path, capsys, key, value, message, command):
    import re

    run = push_run(tmp_path / "run")
    config = run.path / "config.yaml"
    text, n = re.subn(rf"(?m)^{key}: .*$", f"{key}: {value}", config.read_text())
    assert n == 1
    config.write_text(text)
    before = snapshot(run.path)
    code, err = invoke(capsys, command, *(["push", "--resume"] if command == "train" else []), run.path)
    error_line(code, err, command, f"{config}: {key} (line ", message)
    assert snapshot(run.path) == before


def test_experiment_yaml_values_over_their_bound_are_one_located_error(tmp_path):
    from mjxskill.errors import RunError
    from mjxskill.experiment.directory import Protocol

    good = "format: mjxskill.experiment/1\ntask: push\nper_config: 2\nrandom_sets: 3\nmax_force: null\n"
    for old, new, message in [("per_config: 2", "per_config: 100000", "per_config (line 3): expected an integer <= 1000"),
                              ("random_sets: 3", "random_sets: 1000000000", "random_sets (line 4): expected an integer <= 10000")]:
        with pytest.raises(RunError, match=message.replace("(", r"\(").replace(")", r"\)")):
            Protocol.from_yaml(good.replace(old, new), "exp/experiment.yaml")
    assert Protocol.from_yaml(good.replace("per_config: 2", "per_config: 1000"), "exp/experiment.yaml").per_config == 1000
