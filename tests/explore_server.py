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
