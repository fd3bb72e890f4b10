"""The explore page answers only its own origin: requests sent with
http.client and raw sockets to a real server on loopback, so that Host, Origin, Content-Type
and Content-Length are what a hostile page or client would send."""

from mjxskill.evaluation.render import default_gl

default_gl()  # MUJOCO_GL=egl when headless; must precede the first import of mujoco

import json  # noqa: E402
import os  # noqa: E402
import re  # noqa: E402
import signal  # noqa: E402
import socket  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402

from cli_helpers import ROOT  # noqa: E402
from explore_runs import make_push_run  # noqa: E402
from explore_server import get_json, request, serving  # noqa: E402
from mjxskill.explore.guard import MAX_BODY_BYTES  # noqa: E402
from mjxskill.explore.solutions import MAX_WAITING_JOBS, Solutions  # noqa: E402

EVIL = "http://evil.example.com"


@pytest.fixture
def push_run(tmp_path):
    return make_push_run(tmp_path / "push-0")


def _port(base: str) -> int:
    return int(base.rsplit(":", 1)[1])


def _listing(path: Path) -> list[str]:
    return sorted(str(p.relative_to(path)) for p in path.rglob("*"))


# -- Host ----------------------------------------------------------------------------------------
def test_a_request_naming_another_host_reads_nothing(push_run):
    with serving(push_run.path) as base:
        port = _port(base)
        for host in ("evil.example.com", f"evil.example.com:{port}", f"127.0.0.1:{port + 1}", f"localhost.evil.com:{port}",
                     "127.0.0.1", f"[::1]x:{port}", f"127.0.0.1:{port}0"):
            for path in ("/", "/api/run", "/api/front", "/files/config.yaml", "/files/.lock", "/static/app.js"):
                status, body, _ = request(base, path, headers={"Host": host})
                assert status == 403, (host, path)
                assert json.loads(body)["error"] == f"refused: Host {host!r} is not an address this server serves"
        status, body, _ = request(base, "/api/run", headers={"Host": None})  # no Host at all
        assert status == 403
        for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"LOCALHOST:{port}", f"[::1]:{port}"):
            status, body, _ = request(base, "/files/config.yaml", headers={"Host": host})
            assert status == 200 and body == (push_run.path / "config.yaml").read_bytes(), host


# -- state-changing requests ---------------------------------------------------------------------
@pytest.mark.parametrize("headers", [
    {"Origin": EVIL, "Content-Type": "text/plain"},            # a "simple" request: no preflight
    {"Origin": EVIL},                                          # JSON, from another site
    {"Origin": "null"},                                        # a sandboxed frame or a file: page
    {"Origin": None},                                          # neither Origin nor Sec-Fetch-Site
    {"Origin": None, "Sec-Fetch-Site": "cross-site"},
    {"Origin": None, "Sec-Fetch-Site": "same-site"},
    {"Content-Type": "text/plain"},                            # the page's origin, but not JSON
    {"Content-Type": "application/x-www-form-urlencoded"},
    {"Content-Type": None},
])
def test_a_post_not_from_the_page_writes_and_starts_nothing(push_run, headers):
    before = _listing(push_run.path)
    solutions = Solutions(push_run.path, lambda entry: pytest.fail("a rollout was built"), per_config=1)
    with serving(push_run.path, solutions) as base:
        status, body, _ = request(base, "/api/export", {"run": 0, "k": 0}, headers)
        assert status == 403 and json.loads(body)["error"].startswith("refused: POST")
        status, body, _ = request(base, "/api/solution/0/0", {"config": 0}, headers)
        assert status == 403
        assert get_json(base, "/api/solution/0/0?config=0")[1]["job"] is None
    assert _listing(push_run.path) == before and solutions._worker is None


def test_the_pages_own_posts_are_answered(push_run):
    with serving(push_run.path) as base:
        port = _port(base)
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 0},  # as Chromium sends it without Origin
                               {"Origin": None, "Sec-Fetch-Site": "same-origin", "Content-Type": "application/json; charset=utf-8"})
        assert status == 200 and (push_run.path / "selected-0" / "parameters.yaml").is_file()
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 1},  # the page opened as localhost
                               {"Host": f"localhost:{port}", "Origin": f"http://localhost:{port}"})
        assert status == 200 and (push_run.path / "selected-1" / "parameters.yaml").is_file()
        status, doc = get_json(base, "/api/export", {"run": 0, "k": 2},  # an Origin of another loopback name
                               {"Host": f"localhost:{port}", "Origin": f"http://127.0.0.1:{port}"})
        assert status == 403 and not (push_run.path / "selected-2").exists()


# -- body size -----------------------------------------------------------------------------------
def _raw(port: int, head: str, body: bytes = b"") -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=30) as sock:
        sock.sendall(head.encode() + body)
        reply = b""
        while chunk := sock.recv(65536):
            reply += chunk
    return reply


def _post_head(port: int, length_header: str) -> str:
    return (f"POST /api/export HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nOrigin: http://127.0.0.1:{port}\r\n"
            f"Content-Type: application/json\r\n{length_header}\r\n\r\n")


def test_a_body_over_the_limit_is_refused_unread(push_run):
    before = _listing(push_run.path)
    with serving(push_run.path) as base:
        port = _port(base)
        reply = _raw(port, _post_head(port, "Content-Length: 300000000"))  # stated, never sent: not waited for
        assert reply.startswith(b"HTTP/1.0 413 ") and b"at most 65536 are read" in reply
        reply = _raw(port, _post_head(port, f"Content-Length: {MAX_BODY_BYTES + 1}"))
        assert reply.startswith(b"HTTP/1.0 413 ")
        reply = _raw(port, _post_head(port, "Transfer-Encoding: chunked"), b"5\r\n{}   \r\n0\r\n\r\n")
        assert reply.startswith(b"HTTP/1.0 411 ")

        # a client that sends 300 MB anyway is cut off after what the sockets' buffers hold
        sent = 0
        with socket.create_connection(("127.0.0.1", port), timeout=30) as sock:
            sock.sendall(_post_head(port, "Content-Length: 300000000").encode())
            block = b" " * 65536
            with pytest.raises(OSError):  # broken pipe or reset once the server has closed
                while sent < 300_000_000:
                    sent += sock.send(block)
        assert sent < 64_000_000
        assert get_json(base, "/api/run")[0] == 200  # still serving
    assert _listing(push_run.path) == before


# -- rollout jobs --------------------------------------------------------------------------------
class HeldFactory:
    """A rollout factory held until ``release`` is set, then failing: the first job stays
    running while the test fills the queue, and nothing is ever rolled out."""

    def __init__(self):
        self.release, self.calls = threading.Event(), 0

    def __call__(self, entry):
        self.calls += 1
        self.release.wait(60)
        raise RuntimeError("held stand-in: no rollout")


def test_bad_start_configurations_are_refused_not_queued(push_run):
    factory = HeldFactory()
    with serving(push_run.path, Solutions(push_run.path, factory, per_config=1)) as base:
        for config in (-1, 4, 99, 10**30, "1e3", True, None, 1.5):
            status, doc = get_json(base, "/api/solution/0/0", {"config": config})
            assert status == 400, (config, doc)
            query = json.dumps(config) if not isinstance(config, str) else config
            status, doc = get_json(base, f"/api/solution/0/0?config={query}")
            assert status == 400, (config, doc)
        for run, index in ((0, -1), (0, 10**30), (1, 0), (-1, 0), (10**30, 0)):
            status, doc = get_json(base, f"/api/solution/{run}/{index}", {"config": 0})
            assert status == 400, (run, index, doc)
        factory.release.set()
    assert factory.calls == 0 and not (push_run.path / "explore").exists()


def test_one_job_per_point_and_a_bounded_queue(push_run):
    factory = HeldFactory()
    solutions = Solutions(push_run.path, factory, per_config=1)
    try:
        with serving(push_run.path, solutions) as base:
            assert get_json(base, "/api/solution/0/0", {"config": 0})[0] == 200
            status, doc = get_json(base, "/api/solution/0/0", {"config": 0})  # the same: its job's progress
            assert status == 200 and doc["job"]["state"] in ("queued", "running")
            status, doc = get_json(base, "/api/solution/0/0", {"config": 1})  # the same point, another world
            assert status == 409 and doc["error"].startswith("run 0, evaluation 0 is already being rolled out")
            for _ in range(200):  # the first job leaves the queue for the worker
                if get_json(base, "/api/solution/0/0?config=0")[1]["job"]["state"] == "running":
                    break
                time.sleep(0.05)
            for index in range(1, 1 + MAX_WAITING_JOBS):
                assert get_json(base, f"/api/solution/0/{index}", {"config": 0})[0] == 200
            status, doc = get_json(base, f"/api/solution/0/{MAX_WAITING_JOBS + 1}", {"config": 0})
            assert status == 429
            assert doc["error"] == (f"the rollout queue is full ({MAX_WAITING_JOBS} points waiting, at most {MAX_WAITING_JOBS}); "
                                    "ask again when one is done")
            assert get_json(base, f"/api/solution/0/{MAX_WAITING_JOBS + 1}?config=0")[1]["job"] is None
            assert get_json(base, "/api/front")[0] == 200  # the server still answers
    finally:
        factory.release.set()
    solutions._worker.join(timeout=30)
    assert factory.calls <= 1 + MAX_WAITING_JOBS  # every job failed; none more was made


# -- Ctrl-C --------------------------------------------------------------------------------------
def test_ctrl_c_while_a_rollout_runs_ends_the_server_with_130(push_run):
    """The run's own engine (native, worker processes) rolls out a point in the server's job
    thread when SIGINT arrives; the process ends with 130 and one line, no abort."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "mjxskill.explore", str(push_run.path), "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    with proc:
        try:
            line = proc.stdout.readline()
            match = re.search(r"at (http://127\.0\.0\.1:\d+)/", line)
            assert match, (line, proc.stderr.read() if proc.poll() is not None else "")
            base = match.group(1)
            assert get_json(base, "/api/solution/0/0", {"config": 0})[0] == 200
            for _ in range(1200):
                job = get_json(base, "/api/solution/0/0?config=0")[1]["job"]
                if job["state"] != "queued" and job["stage"].startswith("rolling out"):
                    break
                assert job["state"] in ("queued", "running"), job
                time.sleep(0.1)
            time.sleep(0.5)  # inside the rollout's worker processes
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 130, err[-3000:]
    assert err.strip().splitlines() == ["mjxskill.explore: interrupted"], err[-3000:]
