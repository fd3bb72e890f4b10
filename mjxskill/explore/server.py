"""The explore page's HTTP server: the page, its JSON API and the files of the run directory.

Routing, JSON responses and static files (content types, ranges for the video, conditional
requests) come from Bottle, one module with no dependencies; it runs on the standard library's
WSGI server made threaded, so a slow request (a long video) never holds up another. What is
served:

    /                        the page;  /static/<file>  its scripts, styles and D3 (package data)
    /files/<path>            a file inside the run directory (frames and videos the page made)
    /api/run                 task, parameters with units and bounds, objectives, runs
    /api/front               the rows of every run's pareto.csv with their values
    /api/evaluations         every evaluation (run, row, values, Pareto row k or null)
    /api/hypervolume         each run's hypervolume after each batch
    /api/choose?min_success=R&max_force=N    the Pareto solution select picks for these limits
    /api/solution/<run>/<index>?config=C     per-world results and rendering of a point, progress
    POST /api/solution/<run>/<index>  {"config": C}   start computing them (background)
    POST /api/export {"run": r, "k": k}      write selected-<k>/ as ``select --pick k``

Before any routing, a request is refused (``mjxskill.explore.guard``) whose Host is not an
address this server serves (403), a state-changing one not sent by the page itself with a JSON
body (403), and a body over ``MAX_BODY_BYTES`` (413); so is a path with a ``..`` segment, a
backslash or a NUL (403). A file is served only when its real path (symlinks resolved) lies
inside the static folder or the run directory.

Every error a request meets is answered by one handler (``error_response``, installed on every
route as a Bottle plugin, and Bottle's own errors such as 404 and 405) with a JSON body
``{"error": message}`` and logged as one line on the server's stderr (``mjxskill.explore: error:
METHOD PATH -> STATUS: message``), never a traceback: bad input to the API answers 400; a
rollout the server cannot take now 409 (that point has one under way) or 429 (the queue is
full); a fault of the machine (a full disk: 507; a file system gone read-only, another
OSError: 500) and anything unexpected 500, the message naming the file where there is one.
"""

from __future__ import annotations

import errno
import json
import socket
import socketserver
import sys
from pathlib import Path
from wsgiref.simple_server import WSGIRequestHandler, WSGIServer, make_server

import bottle

from mjxskill.errors import RequestError, RunError, ServerBusy, UserError, quote, shortened
from mjxskill.explore.data import (
    choose_document,
    evaluations_document,
    front_document,
    hypervolume_document,
    point,
    run_document,
    runs_in,
)
from mjxskill.explore.export import export_solution
from mjxskill.explore.guard import ServedAddress, refusal, served_address
from mjxskill.explore.solutions import Solutions

STATIC = Path(__file__).resolve().parent / "static"


class Explorer:
    """The run directory ``path`` (a run, or a repeated run) and its on-demand rollouts."""

    def __init__(self, path: Path | str, solutions: Solutions | None = None):
        self.path = Path(path)
        runs_in(self.path)  # a bad directory fails here, before a server starts
        self.solutions = solutions or Solutions(self.path)

    def entries(self):
        return runs_in(self.path)  # read again on every request: a run may be training on

    def close(self) -> None:
        """Closes the on-demand rollouts (after the server stopped serving)."""
        self.solutions.close()


PROG = "mjxskill.explore"
SPACE = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)  # faults that freeing space cures: 507


def _json(status: int, doc: dict) -> bottle.HTTPResponse:
    return bottle.HTTPResponse(json.dumps(doc), status, {"Content-Type": "application/json"})


def error_status(err: BaseException) -> tuple[int, str]:
    """(HTTP status, one-line message) of an error a request met (module doc)."""
    if isinstance(err, ServerBusy):
        status, message = err.status, str(err)
    elif isinstance(err, UserError):
        status, message = 400, str(err)
    elif isinstance(err, OSError):
        where = f" ({err.filename})" if err.filename else ""  # shortened below
        status = 507 if err.errno in SPACE else 500
        message = f"{err.strerror or type(err).__name__}{where}: the server could not finish; fix that and ask again"
    else:
        status, message = 500, f"internal error: {type(err).__name__}: {quote(str(err), 300)}"
    return status, shortened(" ".join(message.split()))


def log_error(status: int, message: str) -> None:
    """One line on the server's stderr for an error answered."""
    where = f"{bottle.request.method} {quote(bottle.request.path, 200)}"
    print(f"{PROG}: error: {where} -> {status}: {message}", file=sys.stderr, flush=True)


def error_response(err: BaseException) -> bottle.HTTPResponse:
    """The one answer to an error: JSON ``{"error": message}`` with its status, logged in one line."""
    status, message = error_status(err)
    log_error(status, message)
    return _json(status, {"error": message})


def _guarded(callback):
    """``callback`` with every error it raises answered by ``error_response`` (a Bottle plugin:
    installed on every route); the responses it raises on purpose (a refusal) pass."""
    def wrapper(*args, **kwargs):
        try:
            return callback(*args, **kwargs)
        except bottle.HTTPResponse:
            raise
        except Exception as err:  # noqa: BLE001  (every error: answered as JSON, logged in one line)
            return error_response(err)
    return wrapper


def refused(path: str) -> bool:
    """True for a path that tries to leave where it points (``..``, backslashes, NULs)."""
    return "\\" in path or "\x00" in path or ".." in path.split("/")


def serve_file(root: Path, relative: str):
    """The file ``relative`` inside ``root``, or 403 when its real path lies outside."""
    real_root = root.resolve()
    target = (real_root / relative).resolve()
    if refused(relative) or relative.startswith("/") or not target.is_relative_to(real_root):
        return _json(403, {"error": f"refused: {quote(relative)} is outside the served folder"})
    if not target.is_file():
        return _json(404, {"error": f"no file {quote(relative)}"})
    response = bottle.static_file(target.relative_to(real_root).as_posix(), root=str(real_root))
    response.set_header("Cache-Control", "no-cache")
    return response


def _limit(name: str) -> float | None:
    text = bottle.request.query.get(name, "")
    if text == "":
        return None
    try:
        return float(text)
    except ValueError:
        raise RequestError(f"{name} must be a number, got {quote(text)}") from None


def _body() -> dict:
    try:
        doc = json.loads(bottle.request.body.read() or b"{}")
    except ValueError:
        raise RequestError("the request body is not JSON") from None
    if not isinstance(doc, dict):
        raise RequestError("the request body must be a JSON object")
    return doc


def _int(doc, name: str, default: int | None = None) -> int:
    """The integer ``name`` of a JSON body, or of the query string (``bottle.request.query``)."""
    value = doc.get(name, default)
    if isinstance(value, str):
        try:
            value = int(value)
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, int):
        raise RequestError(f"{name} must be an integer, got {quote(value)}")
    return value


def build_app(explorer: Explorer, served: ServedAddress) -> bottle.Bottle:
    """The page and its API for ``explorer``, answering only requests to ``served``."""
    app = bottle.Bottle()
    app.install(_guarded)  # every route's errors: JSON, one log line

    def _error_page(error: bottle.HTTPError) -> str:  # Bottle's own errors (no such route: 404, 405)
        message = shortened(" ".join(str(error.body or error.status_line).split()))
        log_error(error.status_code, message)
        bottle.response.content_type = "application/json"
        return json.dumps({"error": message})

    app.default_error_handler = _error_page  # type: ignore[method-assign]

    @app.hook("before_request")
    def _refuse_foreign_and_escapes():
        try:
            refused_request = refusal(bottle.request.environ, served)
        except Exception as err:  # noqa: BLE001  (answered as every other error is)
            raise error_response(err) from None
        if refused_request is not None:
            raise _json(refused_request[0], {"error": refused_request[1]})
        if refused(bottle.request.path):
            raise _json(403, {"error": f"refused: {quote(bottle.request.path)} leaves the served folders"})

    def solution(run: int, index: int, start: bool):
        config_index = _int(_body() if start else bottle.request.query, "config", 0)
        entry, row = point(explorer.entries(), run, index)
        act = explorer.solutions.start if start else explorer.solutions.status
        return act(run, entry, index, row.params[0], config_index)

    app.get("/")(lambda: serve_file(STATIC, "index.html"))
    app.get("/static/<path:path>")(lambda path: serve_file(STATIC, path))
    app.get("/files/<path:path>")(lambda path: serve_file(explorer.path, path))
    app.get("/api/run")(lambda: run_document(explorer.path, explorer.entries()))
    app.get("/api/front")(lambda: front_document(explorer.entries()))
    app.get("/api/evaluations")(lambda: evaluations_document(explorer.entries()))
    app.get("/api/hypervolume")(lambda: hypervolume_document(explorer.entries()))
    app.get("/api/choose")(lambda: choose_document(explorer.entries(), _limit("max_force"), _limit("min_success")))
    app.get("/api/solution/<run:int>/<index:int>")(lambda run, index: solution(run, index, start=False))
    app.post("/api/solution/<run:int>/<index:int>")(lambda run, index: solution(run, index, start=True))

    @app.post("/api/export")
    def _export():
        doc, entries = _body(), explorer.entries()
        run = _int(doc, "run")
        if not 0 <= run < len(entries):
            raise RunError(f"run {run}: this directory holds runs 0-{len(entries) - 1}")
        return export_solution(entries[run], _int(doc, "k"), explorer.solutions)

    return app


class _ThreadingServer(socketserver.ThreadingMixIn, WSGIServer):
    daemon_threads = True  # a connection left open never keeps the process alive


class _IPv6Server(_ThreadingServer):
    address_family = socket.AF_INET6


class _QuietHandler(WSGIRequestHandler):
    def log_message(self, format, *args):  # noqa: A002  (the page polls; a line per request is noise)
        pass


def make_explore_server(explorer: Explorer, host: str = "127.0.0.1", port: int = 0) -> WSGIServer:
    """A server bound to ``host:port`` (0: a free port; ``server.server_port`` tells which),
    not yet serving: call ``serve_forever()``. A port in use or a bad host is the OSError of
    binding the socket (errno EADDRINUSE for a port in use), which the command line words."""
    server_class = _IPv6Server if ":" in host else _ThreadingServer
    served = served_address(host)
    server = make_server(host, port, build_app(explorer, served), server_class=server_class, handler_class=_QuietHandler)
    served.port = server.server_port  # for port 0, the one the bind chose
    return server
