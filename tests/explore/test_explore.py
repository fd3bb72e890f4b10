"""explore: the JSON API over a run directory, what it refuses, export against select, the
command's errors, and the on-demand rollout (with the native engine standing in for the
compiled one, so that no test waits for an MJX compile)."""

from mjxskill.evaluation.render import default_gl

default_gl()  # MUJOCO_GL=egl when headless; must precede the first import of mujoco

import errno  # noqa: E402
import os  # noqa: E402
import re  # noqa: E402
import socket  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import threading  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from explore_runs import make_push_run, make_repeated_run  # noqa: E402
from explore_server import NativeStandIn, get_json, request, select_export, serving  # noqa: E402
from capabilities import no_render  # noqa: E402
from cli_helpers import HELPERS, ROOT  # noqa: E402
from mjxskill.errors import RunError  # noqa: E402
from mjxskill.explore.solutions import Solutions  # noqa: E402
from mjxskill.explore.data import runs_in  # noqa: E402
from mjxskill.explore.server import Explorer, make_explore_server  # noqa: E402
from mjxskill.evaluation.selection import choose  # noqa: E402


@pytest.fixture(scope="module")
def push_run(tmp_path_factory):
    return make_push_run(tmp_path_factory.mktemp("explore") / "push-0")


@pytest.fixture(scope="module")
def repeated_run(tmp_path_factory):
    return make_repeated_run(tmp_path_factory.mktemp("explore") / "push-x3", repeats=3)


# -- which runs a directory holds ---------------------------------------------------------------
def test_a_run_is_one_entry_and_a_repeated_run_one_per_repetition(push_run, repeated_run):
    assert [(e.label, e.run.path) for e in runs_in(push_run.path)] == [("seed 0", push_run.path)]
    entries = runs_in(repeated_run.path)
    assert [e.label for e in entries] == ["seed 0", "seed 1", "seed 2"]
    assert [e.run.path.name for e in entries] == ["seed-0", "seed-1", "seed-2"]


def test_a_repetition_not_yet_started_is_left_out(tmp_path):
    root = make_repeated_run(tmp_path / "x2", repeats=2)
    (root.path / "seed-1" / "config.yaml").unlink()
    assert [e.label for e in runs_in(root.path)] == ["seed 0"]
    (root.path / "seed-0" / "config.yaml").unlink()
    with pytest.raises(RunError, match="none has started"):
        runs_in(root.path)


def test_a_folder_without_a_run_is_refused(tmp_path):
    with pytest.raises(RunError, match="is not a run directory"):
        runs_in(tmp_path)


# -- the JSON API ---------------------------------------------------------------------------------
def test_front_is_pareto_csv_and_evaluations_are_evaluations_csv(push_run):
    front, ev = push_run.pareto(), push_run.evaluations()
    with serving(push_run.path) as base:
        status, doc = get_json(base, "/api/front")
        assert status == 200 and len(doc["rows"]) == len(front) > 2
        for k, row in enumerate(doc["rows"]):
            assert (row["run"], row["k"]) == (0, k)
            assert row["params"] == front.params[k].tolist() and row["objectives"] == front.objectives[k].tolist()
            assert (row["success_rate"], row["peak_contact_force"], row["peak_commanded_force"]) == (
                front.success_rate[k], front.peak_contact_force[k], front.peak_commanded_force[k])
            assert ev.params[row["index"]].tolist() == row["params"]  # the point's row in evaluations.csv
        status, doc = get_json(base, "/api/evaluations")
        assert status == 200 and len(doc["rows"]) == len(ev)
        assert [r["params"] for r in doc["rows"]] == ev.params.tolist()
        assert sorted(r["k"] for r in doc["rows"] if r["k"] is not None) == list(range(len(front)))
        status, doc = get_json(base, "/api/run")
        assert [(p["name"], p["unit"]) for p in doc["parameters"]] == list(zip(push_run.config().parameter_names,
                                                                               push_run.config().parameter_units))
        status, doc = get_json(base, "/api/hypervolume")
        curve = doc["curves"][0]
        assert curve["evaluations"] == [6, 12, 18, 24, 30] and np.all(np.diff(curve["hypervolume"]) >= 0)
    assert not (push_run.path / "run_state.json").exists()  # reading writes nothing into the run


def test_repeated_runs_serve_every_repetition(repeated_run):
    with serving(repeated_run.path) as base:
        _, doc = get_json(base, "/api/front")
        for r, entry in enumerate(runs_in(repeated_run.path)):
            rows = [row for row in doc["rows"] if row["run"] == r]
            assert [row["params"] for row in rows] == entry.run.pareto().params.tolist()
        _, doc = get_json(base, "/api/run")
        assert [r["label"] for r in doc["runs"]] == ["seed 0", "seed 1", "seed 2"]


def test_choose_is_selects_rule(push_run):
    front = push_run.pareto()
    with serving(push_run.path) as base:
        for limits in ({"max_force": 20.0}, {"min_success": 0.5}, {"max_force": 15.0, "min_success": 0.25}):
            query = "&".join(f"{k}={v}" for k, v in limits.items())
            status, doc = get_json(base, f"/api/choose?{query}")
            assert status == 200 and doc == {"run": 0, "k": choose(front, limits.get("max_force"), limits.get("min_success"))}
        status, doc = get_json(base, "/api/choose?max_force=0")
        assert status == 400 and "no Pareto solution meets --max-force" in doc["error"]
        status, doc = get_json(base, "/api/choose?max_force=lots")
        assert status == 400 and "max_force must be a number" in doc["error"]


# -- what is refused ------------------------------------------------------------------------------
def test_paths_outside_the_run_and_the_static_folder_are_refused(tmp_path):
    run = make_push_run(tmp_path / "runs" / "push-0")
    other = (tmp_path / "runs" / "config.yaml")
    other.write_text("secret: the other run\n")
    (run.path / "escape.yaml").symlink_to(other)
    (run.path / "inside.yaml").symlink_to(run.path / "config.yaml")
    with serving(run.path) as base:
        for path in ["/../config.yaml", "/files/../config.yaml", "/files/%2e%2e/config.yaml", "/files/..%2fconfig.yaml",
                     "/static/../../../../../../etc/passwd", "/static/..%5c..%5cserver.py", "/files//etc/passwd",
                     "/files/escape.yaml", "/api/../files/../config.yaml"]:
            status, body, _ = request(base, path)
            assert status == 403, path
            assert b"secret" not in body and b"root:" not in body, path
        assert request(base, "/files/config.yaml")[0] == 200  # inside the run directory
        assert request(base, "/files/inside.yaml")[1] == (run.path / "config.yaml").read_bytes()  # a link that stays inside
        status, body, kind = request(base, "/static/app.js")
        assert status == 200 and "javascript" in kind and b"drawPareto" in body
        assert request(base, "/static/d3.LICENSE.txt")[0] == 200
        assert request(base, "/files/no-such-file")[0] == 404


def test_the_page_loads_nothing_from_other_hosts():
    from mjxskill.explore.server import STATIC

    for path in STATIC.iterdir():
        if path.suffix in (".html", ".css") or path.name in ("app.js", "plot.js"):
            assert not re.search(r"(src|href)=[\"']?(https?:)?//|url\(\s*[\"']?(https?:)?//|fetch\([\"']https?:",
                                 path.read_text()), path


# -- export ---------------------------------------------------------------------------------------
def test_export_writes_the_files_select_writes(tmp_path):
    run = make_push_run(tmp_path / "push-0")
    with serving(run.path) as base:
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 2})
        assert status == 200 and doc["folder"] == str(run.path / "selected-2")
        exported = {p.name: p.read_bytes() for p in sorted((run.path / "selected-2").iterdir())}
        assert exported == select_export(run.path, 2, tmp_path / "by-select")
        assert get_json(base, "/api/export", {"run": 0, "k": 2})[0] == 200  # the same again: nothing changes
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 99})
        assert status == 400 and "Pareto row 99" in doc["error"]


def test_export_of_a_repetition_is_selects_export_of_that_sub_run(tmp_path):
    root = make_repeated_run(tmp_path / "push-x2", repeats=2)
    with serving(root.path) as base:
        assert get_json(base, "/api/export", {"run": 1, "k": 0})[0] == 200
    exported = {p.name: p.read_bytes() for p in sorted((root.path / "seed-1" / "selected-0").iterdir())}
    assert exported == select_export(root.path / "seed-1", 0, tmp_path / "by-select")


def test_export_never_replaces_a_different_file(tmp_path):
    run = make_push_run(tmp_path / "push-0")
    folder = run.path / "selected-1"
    folder.mkdir()
    (folder / "parameters.yaml").write_text("edited by hand\n")
    with serving(run.path) as base:
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 1})
    assert status == 400 and "holds other content" in doc["error"] and "it is kept" in doc["error"]
    assert (folder / "parameters.yaml").read_text() == "edited by hand\n"
    assert not (folder / "parameters.json").exists()


# -- the command ----------------------------------------------------------------------------------
def test_a_bad_run_directory_is_one_error_line(tmp_path, capsys):
    from mjxskill.cli.explore import main

    assert main([str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mjxskill.explore: error:") and "nowhere" in err[0]


def test_a_port_in_use_is_one_error_line_naming_it(push_run, capsys):
    from mjxskill.cli.explore import main

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main([str(push_run.path), "--port", str(port)]) == 2
        with pytest.raises(OSError) as refused:  # the library's own: the command line words it
            make_explore_server(Explorer(push_run.path), "127.0.0.1", port)
        assert refused.value.errno == errno.EADDRINUSE
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"mjxskill.explore: error: port {port} on 127.0.0.1 is in use; choose another with --port N (0: any free port)"]


def test_a_bad_port_is_refused_by_the_parser(push_run, capsys):
    from mjxskill.cli.explore import main

    with pytest.raises(SystemExit) as stop:
        main([str(push_run.path), "--port", "70000"])
    assert stop.value.code == 2 and "0-65535" in capsys.readouterr().err


def test_the_command_serves_the_run_on_loopback(push_run):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "mjxskill.explore", str(push_run.path), "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    with proc:  # closes its pipes after the wait below
        try:
            line = proc.stdout.readline()
            match = re.fullmatch(rf"exploring {re.escape(str(push_run.path))} at (http://127\.0\.0\.1:\d+)/ \(Ctrl-C stops\)\n", line)
            assert match, (line, proc.stderr.read() if proc.poll() is not None else "")
            status, doc = get_json(match.group(1), "/api/front")
            assert status == 200 and len(doc["rows"]) == len(push_run.pareto())
        finally:
            proc.terminate()
            proc.wait(timeout=30)


# -- the on-demand rollout ------------------------------------------------------------------------
def wait_for_job(base: str, path: str) -> dict:
    for _ in range(1200):
        status, doc = get_json(base, path)
        assert status == 200
        if doc["job"] and doc["job"]["state"] in ("done", "failed"):
            return doc
        threading.Event().wait(0.1)
    raise AssertionError(f"job {path} did not finish: {doc['job']}")


def test_a_point_is_rolled_out_on_demand_without_blocking_the_server(tmp_path):
    from mjxskill.evaluation.baselines import evaluation_worlds

    run = make_push_run(tmp_path / "push-0")
    gate = threading.Event()
    standin = NativeStandIn(gate)
    solutions = Solutions(run.path, standin, per_config=1, size=(64, 48))
    front = run.pareto()
    index = int(np.flatnonzero((run.evaluations().params == front.params[0]).all(axis=1))[0])
    path = f"/api/solution/0/{index}"
    with serving(run.path, solutions) as base:
        assert get_json(base, f"{path}?config=0")[1]["job"] is None  # nothing asked yet
        status, doc = get_json(base, path, {"config": 1})
        assert status == 200 and doc["job"]["state"] in ("queued", "running")
        for _ in range(100):  # the worker is inside the "compile": the server still answers
            status, doc = get_json(base, f"{path}?config=1")
            if doc["job"]["stage"].startswith("loading the scenario and building the rollout"):
                break
            threading.Event().wait(0.05)
        assert doc["job"]["state"] == "running" and doc["worlds"] is None
        assert get_json(base, "/api/front")[0] == 200
        gate.set()
        doc = wait_for_job(base, f"{path}?config=1")
        assert doc["job"]["state"] == "done", doc["job"]

        # success per world and per start configuration: the native engine's in evaluate's worlds
        worlds, names, known = evaluation_worlds(standin.built, 1, 0)
        out = standin.built.run_worlds(front.params[:1], worlds)
        got = doc["worlds"]
        assert [c["name"] for c in got["configs"]] == list(names) and [c["known"] for c in got["configs"]] == known.tolist()
        assert [w["success"] for c in got["configs"] for w in c["worlds"]] == np.asarray(out.success)[0].tolist()
        np.testing.assert_allclose([w["peak_contact_force"] for c in got["configs"] for w in c["worlds"]],
                                   out.metrics["peak_contact_force"][0])
        assert (run.path / "explore" / f"evaluation-{index}" / "worlds.json").is_file()

        if doc["video"] is None:  # no OpenGL here: the page says so and the rest works
            assert "no video" in doc["job"]["message"] and "MUJOCO_GL" in doc["job"]["message"]
            no_render(doc["job"]["message"])
        frames = doc["video"]["urls"]
        assert doc["video"]["kind"] in ("png", "mp4") and frames[0].startswith(f"/files/explore/evaluation-{index}/known-1")
        status, body, kind = request(base, frames[0])
        assert status == 200 and kind in ("image/png", "video/mp4") and len(body) > 100

        # a second request is answered from the run directory, with nothing computed again
        status, again = get_json(base, path, {"config": 1})
        assert again["worlds"] == got and again["video"] == doc["video"] and standin.calls == 1
    # results of other settings are not taken for these
    entry = runs_in(run.path)[0]
    other = Solutions(run.path, standin, per_config=2, size=(64, 48)).status(0, entry, index, front.params[0], 1)
    assert other["worlds"] is None and other["video"] is not None
    other = Solutions(run.path, standin, per_config=1, size=(80, 60)).status(0, entry, index, front.params[0], 1)
    assert other["worlds"] == got and other["video"] is None


def test_export_copies_the_rendering_the_page_made(tmp_path):
    run = make_push_run(tmp_path / "push-0")
    standin = NativeStandIn()
    solutions = Solutions(run.path, standin, per_config=1, size=(64, 48))
    front = run.pareto()
    index = int(np.flatnonzero((run.evaluations().params == front.params[1]).all(axis=1))[0])
    with serving(run.path, solutions) as base:
        get_json(base, f"/api/solution/0/{index}", {"config": 0})
        doc = wait_for_job(base, f"/api/solution/0/{index}?config=0")
        if doc["video"] is None:
            no_render(doc["job"]["message"])
        status, export = get_json(base, "/api/export", {"run": 0, "k": 1})
    assert status == 200
    copied = run.path / "selected-1" / ("frames" if doc["video"]["kind"] == "png" else "episode.mp4")
    assert str(copied) in export["written"]
    cache = run.path / "explore" / f"evaluation-{index}"
    if copied.is_dir():
        assert sorted(p.name for p in copied.iterdir()) == sorted(Path(f).name for f in doc["video"]["files"])
        assert all((copied / Path(f).name).read_bytes() == (cache / f).read_bytes() for f in doc["video"]["files"])


def test_a_point_is_rolled_out_on_the_runs_own_engine(tmp_path, monkeypatch):
    import dataclasses

    import mjxskill.engine.build as build
    from mjxskill.explore.solutions import build_for

    entry = runs_in(make_push_run(tmp_path / "push-0").path)[0]
    asked = []
    monkeypatch.setattr(build, "build_rollout", lambda scn, task, engine, **settings: asked.append((engine, settings)))
    for engine in ("native", "mjx"):
        build_for(dataclasses.replace(entry, config=dataclasses.replace(entry.config, engine=engine)))
    settings = {"worlds": 1, "episode_seconds": entry.config.episode_seconds}
    assert asked == [("native", settings), ("mjx", settings)]


class Closable:
    """A rollout that fails at once (no scenario) and counts its closes."""

    def __init__(self):
        self.closed = 0

    def __call__(self, entry):
        return self

    def close(self):
        self.closed += 1


def test_closing_the_explorer_closes_the_rollouts_it_built(tmp_path):
    run = make_push_run(tmp_path / "push-0")
    entry, ev = runs_in(run.path)[0], run.evaluations()
    rollout = Closable()
    solutions = Solutions(run.path, rollout, per_config=1)
    solutions.start(0, entry, 0, ev.params[0], 0)
    for _ in range(600):
        if (doc := solutions.status(0, entry, 0, ev.params[0], 0))["job"]["state"] == "failed":
            break
        threading.Event().wait(0.05)
    assert doc["job"]["state"] == "failed" and rollout.closed == 0  # built, kept for the next point
    solutions.close()
    assert rollout.closed == 1
    solutions._worker.join(timeout=30)
    assert not solutions._worker.is_alive()  # the worker ended too
    solutions.close()
    assert rollout.closed == 1  # each rollout once


NO_DISPLAY_SCRIPT = """
import sys, time
sys.path.insert(0, sys.argv[1])
import mjxskill
from explore_runs import make_push_run
from explore_server import NativeStandIn
from mjxskill.explore.solutions import Solutions
from mjxskill.explore.data import runs_in

run = make_push_run(__import__("pathlib").Path(sys.argv[2]))
entry, ev = runs_in(run.path)[0], run.evaluations()
solutions = Solutions(run.path, NativeStandIn(), per_config=1, size=(32, 24))
for config in (0, 1):
    solutions.start(0, entry, 0, ev.params[0], config)
    while (doc := solutions.status(0, entry, 0, ev.params[0], config))["job"]["state"] not in ("done", "failed"):
        time.sleep(0.05)
    print(config, doc["job"]["state"], doc["worlds"] is not None, doc["video"] is None, doc["job"]["message"][:60], flush=True)
"""


def test_a_renderer_that_failed_once_is_not_tried_again(tmp_path):
    """GLFW without a display: MuJoCo's first context fails, and a second attempt in the same
    process aborts it (libc++abi: recursive initialization of a static in mjr_makeContext) or,
    from another thread, hangs holding the GIL: the whole server with it. The page asks once."""
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    env.update(MUJOCO_GL="glfw", PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-c", NO_DISPLAY_SCRIPT, str(HELPERS), str(tmp_path / "push-0")],
                          capture_output=True, text=True, env=env, timeout=240)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.splitlines()
    assert lines == [f"{c} done True True the per-world results are ready; no video: MuJoCo's offscree" for c in (0, 1)], done.stdout
