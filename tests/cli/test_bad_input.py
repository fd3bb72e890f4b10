"""Bad input a careful user would try: each one ``error:`` line naming the value and where
it came from, exit code 2, no traceback, and nothing the user wrote or computed changed.

The commands run in this process through their entry points (a subprocess costs seconds of
imports); none of these cases gets as far as compiling a rollout."""

import math
import os
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cli_helpers import ROOT, error_line, invoke, snapshot, subprocess_env
from mjxskill.runs.run_dir import EVALUATIONS, PARETO, RUN_STATE
from push_runs import front_rows, push_run
from scenario_texts import library_text, shipped_text, write_library_copy

PUSH = shipped_text("push")


def line_of(text: str, fragment: str) -> int:
    assert text.count(fragment) == 1, fragment
    return text[: text.index(fragment)].count("\n") + 1


# -- 1: scene references, checked when the scenario loads, before a run directory exists ------
SCENE_CASES = {
    "misspelled body": ("mjcf_body: object ", "mjcf_body: objec ", "objects.ObjectToBePushed-1.mjcf_body", "no body 'objec'; did you mean object?"),
    "misspelled tool site": ("tool_site: tool ", "tool_site: tol ", "robot.tool_site", "no site 'tol'; did you mean tool?"),
    "missing scene": ("scene: /", "scene: {tmp}/nope.xml #", "scene", "does not exist"),
    "scene is a folder": ("scene: /", "scene: {tmp} #", "scene", "is a directory, not an MJCF file"),
    "scene is not MJCF": ("scene: /", "scene: {tmp}/notes.xml #", "scene", "is not a MuJoCo MJCF scene"),
}


@pytest.mark.parametrize("command", ["plan", "train"])
@pytest.mark.parametrize("case", list(SCENE_CASES))
def test_scene_references_are_checked_before_anything_is_written(tmp_path, capsys, command, case):
    old, new, key, message = SCENE_CASES[case]
    (tmp_path / "notes.xml").write_text("my notes, not a scene\n")
    text = PUSH.replace(old, new.format(tmp=tmp_path), 1)
    path = tmp_path / "cell.yaml"
    path.write_text(text)
    out = tmp_path / "out"
    args = [path] if command == "plan" else [path, "--out", out, "--budget", "2", "--init", "2"]
    code, stderr = invoke(capsys, command, *args)
    line = line_of(text, new.format(tmp=tmp_path).split(" #")[0])
    error_line(code, stderr, command, f"{path}: {key} (line {line}): ", message)
    assert not out.exists()  # nothing written: the same --out works once the file is fixed


# -- 3: run files validated when read -------------------------------------------------------------
CONFIG_EDITS = {
    "batch size 0 (looped forever)": ("batch_size: 2", "batch_size: 0", "batch_size", "must be at least 1, got 0"),
    "episode length beyond the bound": ("episode_seconds: 0.2", "episode_seconds: 1.0e+300", "episode_seconds", "must be at most 3600 s"),
    "negative seed": ("seed: 0", "seed: -1", "seed", "must be at least 0, got -1"),
    "warm-up beyond the budget": ("n_init: 2", "n_init: 9", "n_init", "n_init 9 exceeds the budget of 4 evaluations"),
    "unknown key": ("repeats: 1", "repeats: 1\nbogus: 3", "bogus", "unknown key 'bogus'"),
    "a tag": ("worlds: 1", "worlds: !kg 1", "worlds", "the YAML tag !kg is not supported"),
    "bad optimizer option": ("optimizer_options: {}", "optimizer_options: {n_raw: 0}", "optimizer_options.n_raw",
                             "acquisition setting n_raw: expected a positive integer, got 0"),
    "unknown optimizer option": ("optimizer_options: {}", "optimizer_options: {n_rwa: 3}", "optimizer_options.n_rwa",
                                 "unknown acquisition setting 'n_rwa'; valid settings: scalarization, alpha,"),
    "optimizer options at odds": ("optimizer_options: {}", "optimizer_options: {n_raw: 8, n_restarts: 9}", "optimizer_options",
                                  "acquisition setting n_restarts (9) exceeds n_raw (8)"),
    # 9 ** 6 values from a few hundred bytes: a goal that exhausted memory when select printed it
    "alias bomb in the goal": ("goal: (skiros:at skiros:ObjectToBePushed-1 skiros:ObjectGoalPose-1)",
                               "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
                                   f"{k}: &{k} [{', '.join([f'*{j}'] * 9)}]\n" for j, k in zip("abcd", "bcde"))
                               + "goal: [*e, *e, *e, *e, *e, *e, *e, *e, *e]", "goal", "expands to more than 100000 values"),
}


@pytest.mark.parametrize("command", ["train", "evaluate", "select"])
@pytest.mark.parametrize("case", list(CONFIG_EDITS))
def test_a_damaged_config_yaml_is_refused_naming_key_and_line(tmp_path, capsys, command, case):
    old, new, key, message = CONFIG_EDITS[case]
    run = push_run(tmp_path / "run")
    config_path = run.path / "config.yaml"
    text = config_path.read_text()
    assert text.count(old) == 1, old
    config_path.write_text(text.replace(old, new))
    before = snapshot(run.path)
    args = ["push", "--resume", run.path] if command == "train" else [run.path]
    code, stderr = invoke(capsys, command, *args)
    error_line(code, stderr, command, f"{config_path}: {key} (line ", message)
    assert snapshot(run.path) == before


@pytest.mark.parametrize("damage, fragment", [
    ("run_state", f"{RUN_STATE} is not valid JSON"),
    ("evaluations", f"{EVALUATIONS} is missing"),
    ("header", f"{EVALUATIONS} does not have the columns"),
])
def test_damaged_run_files_are_refused_naming_the_file(tmp_path, capsys, damage, fragment):
    run = push_run(tmp_path / "run")
    if damage == "run_state":
        (run.path / RUN_STATE).write_text('{"hv_reference": [1.5, 2')  # cut short
    elif damage == "evaluations":
        (run.path / EVALUATIONS).unlink()
    else:
        (run.path / EVALUATIONS).write_text("iteration,x\n")
    before = snapshot(run.path)
    code, stderr = invoke(capsys, "train", "push", "--resume", run.path)
    error_line(code, stderr, "train", str(run.path), fragment)
    assert snapshot(run.path) == before


# -- 5: --out never overwrites a user's files -----------------------------------------------------
def test_out_refuses_a_folder_of_the_users_files(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    for name, text in {"plan.txt": "my plan\n", "scenario.yaml": "mine\n", EVALUATIONS: "my,data\n1,2\n"}.items():
        (mine / name).write_text(text)
    before = snapshot(mine)
    code, stderr = invoke(capsys, "train", "push", "--out", mine, "--budget", "2", "--init", "2")
    error_line(code, stderr, "train", f"{mine} is not empty and holds no mjxskill run", "plan.txt", "choose another --out")
    assert snapshot(mine) == before and sorted(os.listdir(tmp_path)) == ["mine"]  # nothing beside it either
    (tmp_path / "file").write_text("x")
    code, stderr = invoke(capsys, "train", "push", "--out", tmp_path / "file", "--budget", "2", "--init", "2")
    error_line(code, stderr, "train", "exists and is not a directory")
    assert (tmp_path / "file").read_text() == "x"


def test_out_takes_an_empty_folder_and_refuses_a_run(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    run = push_run(tmp_path / "empty")  # an empty folder is where a run may go
    assert (run.path / "config.yaml").is_file() and not [p for p in os.listdir(tmp_path) if p.endswith(".creating")]
    before = snapshot(run.path)
    code, stderr = invoke(capsys, "train", "push", "--out", run.path, "--budget", "2", "--init", "2")
    error_line(code, stderr, "train", "already holds a run; continue it with --resume")
    assert snapshot(run.path) == before


# -- 6: one writer per run directory --------------------------------------------------------------
HOLDER = """
import sys, time
from mjxskill.runs.run_lock import lock_run
lock = lock_run(sys.argv[1])
print("locked", flush=True)
time.sleep(120)
"""


def test_a_second_writer_is_refused_naming_the_holder(tmp_path, capsys):
    run = push_run(tmp_path / "run")
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(run.path)], cwd=ROOT, env=subprocess_env(),
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        before = snapshot(run.path)
        code, stderr = invoke(capsys, "train", "push", "--resume", run.path)
        error_line(code, stderr, "train", f"{run.path} is being written by another process (pid {holder.pid} on ")
        assert snapshot(run.path) == before
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    with run.lock():  # the holder's end released it, however it ended
        pass


# -- 7: what gave a traceback, or an unclear message ----------------------------------------------
SCENARIO_EDITS = {
    "python tag": ("mass: 2.5", "mass: !!python/name:os.system", "objects.ObjectToBePushed-1.mass", "the YAML tag !!python/name:os.system is not supported"),
    "unit tag": ("mass: 2.5", "mass: !kg 2.5", "objects.ObjectToBePushed-1.mass", "the YAML tag !kg is not supported"),
    "float tag on text": ("mass: 2.5", "mass: !!float abc", "objects.ObjectToBePushed-1.mass", "cannot read 'abc' as float"),
    "episode length in YAML": ("episode_seconds: 12.0", "episode_seconds: 1e300", "episode_seconds", "expected a number <= 3600"),
}


@pytest.mark.parametrize("command", ["plan", "train"])
@pytest.mark.parametrize("case", list(SCENARIO_EDITS))
def test_scenario_values_that_gave_tracebacks_are_one_located_error(tmp_path, capsys, command, case):
    old, new, key, message = SCENARIO_EDITS[case]
    text = PUSH.replace(old, new, 1)
    path = tmp_path / "cell.yaml"
    path.write_text(text)
    code, stderr = invoke(capsys, command, path, *(["--out", tmp_path / "out"] if command == "train" else []))
    line = error_line(code, stderr, command, f"{path}: {key} (line {line_of(text, new)}): ", message)
    assert "--optimizer-option" not in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["plan", "train"])
def test_zero_width_bounds_in_the_skill_library_are_one_located_error(tmp_path, capsys, command):
    # The skills' parameter bounds live in the skill library the scenario includes: the error
    # names that file, the key and the line (and never blames --optimizer-option).
    old = "offset_x_start: {type: float, unit: m, default: 0.0, bounds: [-0.3, 0.3]"
    new = "offset_x_start: {type: float, unit: m, default: 0.0, bounds: [0, 0]"
    library = library_text()
    assert library.count(old) == 1
    edited = library.replace(old, new)
    path = write_library_copy(tmp_path, "push", edited)
    code, stderr = invoke(capsys, command, path, *(["--out", tmp_path / "out"] if command == "train" else []))
    line = error_line(code, stderr, command, f"{tmp_path / 'library.yaml'}: skills.Push.parameters.offset_x_start.bounds "
                      f"(line {line_of(edited, new)}): ", "bounds [0, 0] leave a learnable parameter nothing to learn")
    assert "--optimizer-option" not in line
    assert not (tmp_path / "out").exists()


def test_a_byte_that_is_not_utf8_and_a_huge_file(tmp_path, capsys):
    path = tmp_path / "cell.yaml"
    text = PUSH.replace("    mass: 2.5", "    mass: 2.5 # \udcff", 1).encode("utf-8", "surrogateescape")
    path.write_bytes(text)
    code, stderr = invoke(capsys, "plan", path)
    column = len("    mass: 2.5 # ") + 1
    error_line(code, stderr, "plan", f"{path} (line {line_of(PUSH, 'mass: 2.5')}, column {column}): byte 0xff is not UTF-8 text")
    path.write_text(PUSH + "#" * (2 << 20))  # a 2 MB scenario (20 MB took 144 s and 1.8 GB)
    code, stderr = invoke(capsys, "plan", path)
    error_line(code, stderr, "plan", f"{path}: the scenario file is larger than 1024 KiB")


@pytest.mark.parametrize("args, message", [
    (["train", "push", "--seed", str(2**32)], "argument --seed: must be at most 4294967295, got 4294967296"),
    (["train", "push", "--episode-seconds", "1e300"], "argument --episode-seconds: must be at most 3600 s, got 1e+300"),
    (["train", "push", "--seed", "4294967295", "--repeats", "2"], "--repeats 2 make seeds beyond 4294967295"),
    (["evaluate", "{run}", "--seed", str(2**64)], "argument --seed: must be at most 4294967295"),
    (["select", "{run}", "--seed", str(2**32)], "argument --seed: must be at most 4294967295"),
])
def test_seed_and_episode_length_are_bounded_and_the_bound_said(tmp_path, capsys, args, message):
    run = push_run(tmp_path / "run")
    code, stderr = invoke(capsys, *[a.format(run=run.path) for a in args])
    assert code == 2 and message in stderr and "Traceback" not in stderr, stderr


def test_a_cache_dir_that_is_a_file_is_said_once(tmp_path, capsys, monkeypatch):
    blocker = tmp_path / f"cache-file-{os.getpid()}"
    blocker.write_text("not a folder")
    monkeypatch.setenv("MJXSKILL_CACHE_DIR", str(blocker))
    code, stderr = invoke(capsys, "plan", "push")
    assert code == 0, stderr
    warnings = [line for line in stderr.splitlines() if "warning:" in line]
    assert warnings == [f"mjxskill.plan: warning: the compile cache {str(blocker)!r} is not a usable directory "
                        f"(it is a file); compile caches are off, so every run compiles from scratch "
                        f"(set MJXSKILL_CACHE_DIR to a directory, or off)"]
    assert blocker.read_text() == "not a folder"


def test_select_by_force_on_a_front_without_forces(tmp_path, capsys):
    run = push_run(tmp_path / "run")
    front_rows(run, 3, peak_force=[math.nan, math.nan, 7.0])
    code, stderr = invoke(capsys, "select", run.path, "--max-force", "5", "--no-render")
    error_line(code, stderr, "select", "no Pareto solution meets --max-force 5",
               "peak contact forces 7.0-7.0 N (2 not a number: a diverged world)")
    assert not list(run.path.glob("selected-*"))


# -- 9: an empty front is refused by evaluate as by select ----------------------------------------
@pytest.mark.parametrize("command", ["evaluate", "select"])
def test_an_empty_front_is_refused(tmp_path, capsys, command):
    run = push_run(tmp_path / "run")
    front_rows(run, 0)
    before = snapshot(run.path)
    code, stderr = invoke(capsys, command, run.path)
    error_line(code, stderr, command, f"{run.path} has an empty Pareto front ({PARETO} has no rows")
    assert snapshot(run.path) == before


# -- 10: error text bounded: a value is shown to a short prefix, whatever its size --------------
def _scenario_with(value: str, old: str, new: str):
    assert PUSH.count(old) >= 1, old
    return lambda folder: ["plan", _written(folder, PUSH.replace(old, new.format(value), 1))]


def _written(folder, text: str):
    path = folder / "cell.yaml"
    path.write_text(text)
    return path


# entry point -> (value -> (folder -> the command's arguments)): a scenario field or a flag
HUGE_VALUES = {
    "scenario goal": lambda v: _scenario_with(v, "goal: (skiros:at", "goal: ({} skiros:at"),
    "scenario skill library": lambda v: _scenario_with(v, "skill_library: ", "skill_library: {}"),
    "scenario scene": lambda v: _scenario_with(v, "scene: /", "scene: {}/"),
    "scenario body": lambda v: _scenario_with(v, "mjcf_body: object", "mjcf_body: object{}"),
    "scenario number": lambda v: _scenario_with(v, "mass: 2.5", "mass: 2{}"),
    "flag --budget": lambda v: lambda folder: ["train", "push", "--budget", v, "--out", folder / "out"],
    "flag --optimizer-option value": lambda v: lambda folder: ["train", "push", "--optimizer-option", f"n_raw={v}",
                                                               "--out", folder / "out"],
    "flag --optimizer-option name": lambda v: lambda folder: ["train", "push", "--optimizer-option", f"{v}=1",
                                                              "--out", folder / "out"],
    "flag --goal": lambda v: lambda folder: ["plan", "push", "--goal", f"({v})"],
    "a flag no command has": lambda v: lambda folder: ["train", "push", f"--{v}", "1"],
    "flag --out": lambda v: lambda folder: ["train", "push", "--out", folder / v],
    "a run directory": lambda v: lambda folder: ["select", folder / v, "--no-render"],
    "flag --per-config": lambda v: lambda folder: ["evaluate", folder, "--per-config", v],
    "a task name": lambda v: lambda folder: ["plan", v],
}


@pytest.mark.parametrize("entry", list(HUGE_VALUES))
@settings(max_examples=3, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(char=st.sampled_from("x1é"), size=st.sampled_from([5_000, 900_000]))
def test_a_huge_value_anywhere_makes_a_short_error_line(tmp_path_factory, capsys, entry, char, size):
    """A scenario field of 900 KB, a flag of 900 KB: one error line of at most a few hundred
    characters (the value quoted to its prefix and its length), exit 2, nothing written."""
    folder = tmp_path_factory.mktemp("huge")
    args = HUGE_VALUES[entry](char * size)(folder)
    code, stderr = invoke(capsys, *args)
    line = error_line(code, stderr, args[0])
    assert len(line) < 1000, (entry, len(line), line[:300])
    assert len(stderr) < 6000, (entry, len(stderr))  # with argparse's usage lines
    assert sorted(p.name for p in folder.iterdir()) == (["cell.yaml"] if entry.startswith("scenario") else [])
