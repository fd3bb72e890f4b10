"""An explore server on a free loopback port in a thread, and plain HTTP requests to it (raw
paths: a client library would normalize ``/../`` away before sending); the native engine
standing in for the compiled one behind the page's on-demand rollout (``NativeStandIn``), and
what ``select`` exports, to compare the page's export with (``select_export``)."""

from __future__ import annotations

import contextlib
import http.client
import json
import threading
from pathlib import Path

from mjxskill.explore.server import Explorer, make_explore_server
from mjxskill.explore.solutions import Solutions


@contextlib.contextmanager
def serving(path, solutions: Solutions | None = None):
    """Yields the base URL of a server over the run directory ``path``."""
    explorer = Explorer(path, solutions)
    server = make_explore_server(explorer, "127.0.0.1", 0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_port}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join()
        explorer.close()


def request(base: str, path: str, body: dict | None = None, headers: dict | None = None,
            method: str | None = None) -> tuple[int, bytes, str]:
    """(status, body, content type) of GET ``path`` (POST with a JSON ``body``, from the page's
    own origin as a browser sends it), sent as is; ``headers`` replace or add headers (a value of
    None leaves that header out)."""
    host, port = base.removeprefix("http://").split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=30)
    sent = {} if body is None else {"Content-Type": "application/json", "Origin": base}
    sent.update(headers or {})
    skip_host = "Host" in sent
    try:
        conn.putrequest(method or ("GET" if body is None else "POST"), path, skip_host=skip_host, skip_accept_encoding=True)
        data = b"" if body is None else json.dumps(body).encode()
        if body is not None:
            sent.setdefault("Content-Length", str(len(data)))
        for name, value in sent.items():
            if value is not None:
                conn.putheader(name, value)
        conn.endheaders(data or None)
        response = conn.getresponse()
        return response.status, response.read(), response.getheader("Content-Type", "")
    finally:
        conn.close()


def get_json(base: str, path: str, body: dict | None = None, headers: dict | None = None) -> tuple[int, dict]:
    status, data, _ = request(base, path, body, headers)
    return status, json.loads(data)


def select_export(run_path: Path, k: int, out: Path) -> dict[str, bytes]:
    """The files ``python -m mjxskill.select RUN --pick k --no-render`` writes (into ``out``)."""
    from mjxskill.cli.select import main

    assert main([str(run_path), "--pick", str(k), "--no-render", "--out", str(out)]) == 0
    return {p.name: p.read_bytes() for p in sorted(out.iterdir())}


class NativeStandIn:
    """The native engine for the push task in place of the compiled rollout: the same worlds and
    result fields, no compile. ``gate`` (an Event) holds the "compile" until set."""

    def __init__(self, gate: threading.Event | None = None):
        self.gate, self.calls, self.built = gate, 0, None

    def __call__(self, entry):
        from mjxskill.engine.build import build_rollout
        from mjxskill.runs.run_task import scenario_and_task

        self.calls += 1
        if self.gate is not None:
            assert self.gate.wait(60)
        scn, task = scenario_and_task("push")
        self.built = build_rollout(scn, task, "native", worlds=1, episode_seconds=0.5)
        return self.built
