"""evaluate keeps an earlier evaluation made with other settings: it
refuses, naming the settings and the flag that would replace it, and with --replace replaces it."""

from mjxskill.evaluation.render import default_gl

default_gl()

import json  # noqa: E402

from cli_helpers import error_line, invoke  # noqa: E402
from explore_runs import make_push_run  # noqa: E402

# the native engine, a fraction of a second per episode, one world per start configuration
QUICK = ("--engine", "native", "--episode-seconds", "0.3", "--per-config", "1", "--random", "0")


def _files(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_an_evaluation_with_other_settings_is_refused_unless_replace(tmp_path, capsys):
    run = make_push_run(tmp_path / "push-0")
    assert invoke(capsys, "evaluate", run.path, *QUICK)[0] == 0
    folder = run.path / "evaluation"
    first = _files(folder)
    assert json.loads(first["evaluation.json"])["settings"]["per_config"] == 1

    assert invoke(capsys, "evaluate", run.path, *QUICK)[0] == 0  # the same settings: reused, not refused
    assert _files(folder) == first

    other = [*QUICK[:-3], "2", *QUICK[-2:]]  # --per-config 2
    code, err = invoke(capsys, "evaluate", run.path, *other)
    error_line(code, err, "evaluate", str(folder), "--per-config 1", "(--per-config 2)", "--replace")
    assert _files(folder) == first
    code, err = invoke(capsys, "evaluate", run.path, *QUICK[:-1], "1", "--seed", "3")  # --random 1 --seed 3
    error_line(code, err, "evaluate", "--random 0, --seed 0", "(--random 1, --seed 3)")
    assert _files(folder) == first

    assert invoke(capsys, "evaluate", run.path, *other, "--replace")[0] == 0
    assert json.loads((folder / "evaluation.json").read_text())["settings"]["per_config"] == 2
