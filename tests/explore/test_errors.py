"""The explore page's errors: one handler answers every error a request meets
with a JSON body and its status, logged as one line on the server's stderr, never a traceback;
and its export (classes 1, 2) goes through select's writer: a rendering left partial, or a
link or FIFO in its cache, is refused, nothing written."""

from mjxskill.evaluation.render import default_gl

default_gl()

import errno  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from explore_runs import make_push_run  # noqa: E402
from explore_server import get_json, request, serving  # noqa: E402
from mjxskill.explore.data import numbers  # noqa: E402
from mjxskill.explore.solutions import FORMAT, Solutions, _write_json  # noqa: E402
from mjxskill.runs import outputs  # noqa: E402


def _one_log_line(capfd, status: int, fragment: str) -> str:
    err = capfd.readouterr().err
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("mjxskill.explore: error: ") and f"-> {status}:" in lines[0], err
    assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


@pytest.fixture
def run(tmp_path):
    return make_push_run(tmp_path / "push-0")


@pytest.mark.parametrize("fault, status, fragment", [
    (errno.EROFS, 500, "Read-only file system"),   # a run on a file system mounted read-only
    (errno.ENOSPC, 507, "No space left on device"),
    (errno.EIO, 500, "Input/output error"),
    (errno.EACCES, 400, "cannot write"),           # a folder the user made read-only: said as bad input
])
def test_an_export_the_machine_cannot_write_is_a_json_error_and_one_log_line(run, monkeypatch, capfd, fault, status,
                                                                               fragment):
    def refused(fd, name, content):
        raise OSError(fault, os.strerror(fault), name)

    before = sorted(p.name for p in run.path.iterdir())
    monkeypatch.setattr(outputs, "_put", refused)
    with serving(run.path) as base:
        capfd.readouterr()
        code, body, kind = request(base, "/api/export", {"run": 0, "k": 1})
    assert code == status and kind == "application/json"
    assert fragment in json.loads(body)["error"]
    _one_log_line(capfd, status, "POST '/api/export'")
    assert sorted(p.name for p in run.path.iterdir()) == before  # the export folder made for it is removed again


def test_an_unexpected_error_is_a_json_500_and_one_log_line(run, monkeypatch, capfd):
    import mjxskill.explore.server as server

    def broken(*_args, **_kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(server, "export_solution", broken)
    monkeypatch.setattr(server, "front_document", broken)
    with serving(run.path) as base:
        capfd.readouterr()
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 1})
        assert status == 500 and doc["error"] == "internal error: ZeroDivisionError: 'a bug'"
        _one_log_line(capfd, 500, "ZeroDivisionError")
        status, doc = get_json(base, "/api/front")
        assert status == 500 and "ZeroDivisionError" in doc["error"]
        _one_log_line(capfd, 500, "GET '/api/front'")
        code, body, kind = request(base, "/api/nowhere")
        assert code == 404 and kind.startswith("application/json") and "error" in json.loads(body)
        _one_log_line(capfd, 404, "/api/nowhere")
        status, doc = get_json(base, "/api/export", {"run": 7, "k": 1})  # bad input: 400, as ever
        assert status == 400 and "run 7" in doc["error"]
        _one_log_line(capfd, 400, "run 7")


# -- the export of the page's rendering ------------------------------------------------------------
def _cached_frames(run, k: int, files: dict[str, bytes]) -> Solutions:
    """A rendering of Pareto row ``k`` in the page's cache, as the page writes it."""
    solutions = Solutions(run.path, lambda entry: None)
    params = run.pareto().params[k]
    index = int(np.flatnonzero((run.evaluations().params == params).all(axis=1))[0])
    cache = Solutions.folder(type("Entry", (), {"run": run})(), index)
    for name, data in files.items():
        (cache / "known-0").mkdir(parents=True, exist_ok=True)
        (cache / "known-0" / name).write_bytes(data)
    _write_json(run.path, cache / "known-0.json", {
        "format": FORMAT, "params": numbers(params), "seed": solutions.seed, "size": list(solutions.size), "kind": "png",
        "fps": 10.0, "world": "known start configuration 0", "files": [f"known-0/{n}" for n in files]})
    return solutions


FRAMES = {"frame_0000.png": b"\x89PNG frame 0", "frame_0001.png": b"\x89PNG frame 1"}


def test_a_partial_rendering_left_in_the_export_is_refused_not_kept(run):
    solutions = _cached_frames(run, 1, FRAMES)
    partial = run.path / "selected-1" / "frames"
    partial.mkdir(parents=True)
    (partial / "frame_0000.png").write_bytes(b"")  # what a renderer killed mid-frame left
    with serving(run.path, solutions) as base:
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 1})
        assert status == 400 and f"{partial} holds other files" in doc["error"]
        assert sorted(p.name for p in (run.path / "selected-1").iterdir()) == ["frames"]  # nothing written
        (partial / "frame_0000.png").unlink()  # the user moves the partial rendering away
        partial.rmdir()
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 1})
    assert status == 200 and str(partial) in doc["written"]
    assert {p.name: p.read_bytes() for p in partial.iterdir()} == FRAMES


@pytest.mark.parametrize("plant", ["fifo", "link", "escape"])
def test_a_fifo_or_link_in_the_pages_cache_is_refused_never_read(run, tmp_path, plant):
    solutions = _cached_frames(run, 1, FRAMES)
    cached = next((run.path / "explore").rglob("frame_0001.png"))
    outside = tmp_path / "outside.png"
    outside.write_bytes(b"the user's")
    cached.unlink()
    if plant == "fifo":
        os.mkfifo(cached)  # reading it would block the request for ever
    elif plant == "link":
        cached.symlink_to(outside)
    else:  # the cache's document naming a file outside it
        listing = cached.parent.parent / "known-0.json"
        doc = json.loads(listing.read_text())
        doc["files"][1] = "../../../outside.png"
        listing.write_text(json.dumps(doc))
    with serving(run.path, solutions) as base:
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 1})
    assert status == 400, doc
    assert not (run.path / "selected-1").exists() and outside.read_bytes() == b"the user's"
