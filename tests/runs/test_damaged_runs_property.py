"""Damaged run directories, generated. A run directory with links out of
it, truncated or garbled files, values of the wrong type and huge values is handed to
``evaluate``, ``select`` and ``train --resume`` (in this process, through their entry points):
each either works (exit 0) or ends with exactly one ``error:`` line, exit code 2, no traceback,
and the directory and the files outside it unchanged."""

from mjxskill.evaluation.render import default_gl

default_gl()

import hashlib  # noqa: E402
import os  # noqa: E402
import shutil  # noqa: E402
import tempfile  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402
import yaml  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from cli_helpers import invoke  # noqa: E402
from explore_runs import evaluations, push_config  # noqa: E402
from mjxskill.runs.run_dir import Run  # noqa: E402
from mjxskill.scenario import load_scenario  # noqa: E402
from mjxskill.training.front import pareto_mask_of  # noqa: E402

FILES = ("config.yaml", "scenario.yaml", "evaluations.csv", "pareto.csv", "run_state.json", "plan.txt")
FOLDERS = ("explore", "evaluation", "selected-0")
CONFIG_KEYS = ("budget", "batch_size", "n_init", "worlds", "seed", "episode_seconds", "repeats", "bounds",
               "parameter_names", "objective_names", "prior", "engine", "optimizer", "task", "optimizer_options")
ODD_VALUES = (-1, 0, 10**30, 1e308, float("inf"), float("nan"), "x", "", [1, 2], {"a": 1}, None, True, [[1e999]])
CELLS = ("1e999", "nan", "-inf", "x", "", "1e308", "99999999999999999999", "1,2", '"')
STATES = ('{"hv_reference": "x"}', "[]", '{"hv_reference": [1e999]}', '{"hv_reference": [1e308, -1e308]}', "null",
          '{"hv_reference": [' + "[" * 100 + "]" * 100 + "]}")
COMMANDS = {
    "evaluate": lambda d: [d, "--per-config", 1, "--random", 0, "--workers", 1],
    "select": lambda d: [d],
    "select --pick": lambda d: [d, "--pick", 0, "--no-render"],
    "train --resume": lambda d: ["push", "--resume", d, "--workers", 1, "--quiet"],
}


@pytest.fixture(scope="module")
def template(tmp_path_factory):
    """A finished push run (random search, native engine, short episodes: cheap to evaluate or
    resume) with the shipped scenario as its copy."""
    config = replace(push_config(), engine="native", episode_seconds=0.2, worlds=1, optimizer="random")
    run = Run(tmp_path_factory.mktemp("template") / "run")
    scn = load_scenario("push")
    run.create(config, scn.source, {"plan.txt": "(GoToLinear) (Push)"})
    ev = evaluations(config, 0)
    run.append(ev)
    run.write_pareto(config, ev, pareto_mask_of(ev))
    run.write_run_state({"hv_reference": [0.0, 0.0]})
    return run.path


damage = st.one_of(
    st.tuples(st.just("link file out"), st.sampled_from(FILES)),
    st.tuples(st.just("link folder out"), st.sampled_from(FOLDERS)),
    st.tuples(st.just("truncate"), st.sampled_from(FILES), st.floats(0, 1)),
    st.tuples(st.just("garble"), st.sampled_from(FILES), st.binary(min_size=1, max_size=64)),
    st.tuples(st.just("config value"), st.sampled_from(CONFIG_KEYS), st.sampled_from(ODD_VALUES)),
    st.tuples(st.just("csv cell"), st.sampled_from(("evaluations.csv", "pareto.csv")), st.integers(0, 40),
              st.integers(0, 20), st.sampled_from(CELLS)),
    st.tuples(st.just("run state"), st.sampled_from(STATES)),
)


def apply(run: Path, outside: Path, change) -> None:
    kind, *args = change
    if kind == "link file out":
        (name,) = args
        target = outside / f"users-{name}"
        if (run / name).exists() and not (run / name).is_symlink():
            shutil.copyfile(run / name, target)
            (run / name).unlink()
        else:
            target.write_text("a file of the user's\n")
        if not os.path.lexists(run / name):
            (run / name).symlink_to(target)
    elif kind == "link folder out":
        (name,) = args
        target = outside / f"users-{name}"
        target.mkdir(exist_ok=True)
        (target / "worlds.json").write_text("{}")
        if not os.path.lexists(run / name):
            (run / name).symlink_to(target)
    elif kind in ("truncate", "garble"):
        name, how = args
        path = run / name
        if path.is_symlink() or not path.is_file():
            return
        data = path.read_bytes()
        path.write_bytes(data[: int(len(data) * how)] if kind == "truncate" else data[: len(data) // 2] + how)
    elif kind == "config value":
        key, value = args
        path = run / "config.yaml"
        try:
            doc = yaml.safe_load(path.read_text())
        except (yaml.YAMLError, UnicodeDecodeError, OSError):
            return
        if isinstance(doc, dict):
            doc[key] = value
            path.write_text(yaml.safe_dump(doc, sort_keys=False))
    elif kind == "csv cell":
        name, row, column, text = args
        path = run / name
        if path.is_symlink() or not path.is_file():
            return
        lines = path.read_bytes().decode("utf-8", "replace").split("\n")
        if 1 + row < len(lines) and lines[1 + row]:
            cells = lines[1 + row].split(",")
            cells[column % len(cells)] = text
            lines[1 + row] = ",".join(cells)
            path.write_text("\n".join(lines))
    else:
        (text,) = args
        if not os.path.islink(run / "run_state.json"):
            (run / "run_state.json").write_text(text)


def fingerprint(folder: Path) -> dict:
    """Every entry below ``folder`` (links not followed): its kind and content or target, but the
    writer's lock (which says who last held it)."""
    out = {}
    for parent, dirs, files in os.walk(folder):
        for name in dirs + files:
            path = os.path.join(parent, name)
            rel = os.path.relpath(path, folder)
            if name == ".lock":
                continue
            if os.path.islink(path):
                out[rel] = ("link", os.readlink(path))
            elif os.path.isdir(path):
                out[rel] = ("dir",)
            else:
                with open(path, "rb") as fh:
                    out[rel] = ("file", hashlib.sha256(fh.read()).hexdigest())
    return out


@settings(max_examples=40, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(changes=st.lists(damage, min_size=1, max_size=2), command=st.sampled_from(list(COMMANDS)))
def test_a_damaged_run_works_or_is_one_error_line_and_unchanged(template, capsys, changes, command):
    with tempfile.TemporaryDirectory() as tmp:
        run, outside = Path(tmp) / "run", Path(tmp) / "outside"
        shutil.copytree(template, run, symlinks=True)
        outside.mkdir()
        for change in changes:
            apply(run, outside, change)
        before, before_outside = fingerprint(run), fingerprint(outside)
        capsys.readouterr()
        name, *sub = command.split(" ", 1)
        code, err = invoke(capsys, name, *COMMANDS[command](run))
        assert "Traceback" not in err, (changes, err)
        assert fingerprint(outside) == before_outside, (changes, code, err)  # nothing outside is ever written
        links_out = [rel for rel, entry in before.items() if entry[0] == "link"]
        if code == 0:
            assert not links_out, (changes, "a link out of the run was followed", err)
            return
        errors = [line for line in err.splitlines() if ": error:" in line]
        assert code == 2 and len(errors) == 1 and errors[0].startswith(f"mjxskill.{name}: error: "), (changes, code, err)
        assert fingerprint(run) == before, (changes, errors[0])
        if links_out:  # refused for the link, named (the first one the walk meets)
            assert "is a symbolic link" in errors[0] and any(str(run / rel) in errors[0] for rel in links_out), errors[0]
