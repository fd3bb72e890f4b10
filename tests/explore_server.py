"""An explore server on a free loopback port in a thread, and plain HTTP requests to it (raw
paths: a client library would normalize ``/../`` away before sending)."""

from __future__ import annotations

import contextlib
import http.client
import json
import threading

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


def request(base: str, path: str, body: dict | None = None) -> tuple[int, bytes, str]:
    """(status, body, content type) of GET ``path`` (POST with a JSON ``body``), sent as is."""
    host, port = base.removeprefix("http://").split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=30)
    try:
        if body is None:
            conn.request("GET", path)
        else:
            conn.request("POST", path, json.dumps(body), {"Content-Type": "application/json"})
        response = conn.getresponse()
        return response.status, response.read(), response.getheader("Content-Type", "")
    finally:
        conn.close()


def get_json(base: str, path: str, body: dict | None = None) -> tuple[int, dict]:
    status, data, _ = request(base, path, body)
    return status, json.loads(data)
