"""Which requests the explore page's server answers at all: checked before any routing, on the
request's headers only, so that a refused request reads, writes or starts nothing.

* Host: a request must name the address the server serves, a loopback name (``127.0.0.1``,
  ``localhost``, ``[::1]``) or the ``--host`` given, with the port it listens on. A page on
  another site that rebinds its own DNS name to 127.0.0.1 sends its own name here and is
  refused (403), so it cannot read the run directory through the user's browser.
* State-changing requests (any method but GET, HEAD and OPTIONS) must come from the page
  itself: an ``Origin`` equal to ``http://`` + the request's Host, or, without ``Origin``,
  ``Sec-Fetch-Site: same-origin``; and a JSON body (``Content-Type: application/json``), which
  another site's form or "simple" fetch cannot send without a preflight this server never
  grants. Else 403.
* A request body is at most ``MAX_BODY_BYTES`` as its ``Content-Length`` states (413 before a
  byte of it is read); a body without a stated length (chunked) is refused with 411.
"""

from __future__ import annotations

import socket
from dataclasses import dataclass

from mjxskill.errors import quote

MAX_BODY_BYTES = 64 * 1024  # the page's largest request is a few dozen bytes of JSON
LOOPBACK_NAMES = frozenset({"127.0.0.1", "localhost", "::1"})
WILDCARD_HOSTS = frozenset({"", "0.0.0.0", "::"})
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


@dataclass
class ServedAddress:
    """The names a request's Host may give and the port the server listens on (``None`` until
    the socket is bound; every request is refused before that)."""

    names: frozenset[str]
    port: int | None = None


def served_address(host: str) -> ServedAddress:
    """The names the server listening on ``host`` answers to: the loopback names and ``host``
    itself; for a wildcard host (every interface) also this machine's host name."""
    names = set(LOOPBACK_NAMES) | {host.strip("[]").lower()}
    if host in WILDCARD_HOSTS:
        names |= {socket.gethostname().lower(), socket.getfqdn().lower()}
    return ServedAddress(frozenset(names - {""}))


def split_host(header: str) -> tuple[str, int] | None:
    """``(name, port)`` of a Host header (``name``, ``name:port``, ``[v6]:port``), or None when
    it is not one."""
    if header.startswith("["):
        name, bracket, rest = header[1:].partition("]")
        if not bracket or (rest and not rest.startswith(":")):
            return None
        port_text = rest[1:] if rest else ""
    else:
        name, _, port_text = header.partition(":")
    if port_text == "":
        return name.lower(), 80
    if not port_text.isdigit() or len(port_text) > 5:
        return None
    return name.lower(), int(port_text)


def refusal(environ: dict, served: ServedAddress) -> tuple[int, str] | None:
    """``(status, message)`` for a request the server must not answer (module doc), else None."""
    host = environ.get("HTTP_HOST", "")
    named = split_host(host)
    if served.port is None or named is None or named[0] not in served.names or named[1] != served.port:
        return 403, f"refused: Host {quote(host)} is not an address this server serves"
    method = environ.get("REQUEST_METHOD", "GET").upper()
    if "chunked" in environ.get("HTTP_TRANSFER_ENCODING", "").lower():
        return 411, "refused: a request body must state its Content-Length"
    length_text = environ.get("CONTENT_LENGTH", "") or "0"
    if not length_text.isdigit():
        return 400, f"Content-Length {quote(length_text)} is not a number of bytes"
    if len(length_text) > 20 or int(length_text) > MAX_BODY_BYTES:  # int() of 5000 digits raises
        return 413, f"refused: a request body of {length_text if len(length_text) <= 20 else quote(length_text, 20)} bytes; at most {MAX_BODY_BYTES} are read"
    if method in SAFE_METHODS:
        return None
    origin = environ.get("HTTP_ORIGIN")
    if origin is not None:
        if origin.lower() != f"http://{host}".lower():
            return 403, f"refused: {method} from origin {quote(origin)}, not from this page (http://{host})"
    elif environ.get("HTTP_SEC_FETCH_SITE", "") != "same-origin":
        return 403, f"refused: {method} without an Origin header or Sec-Fetch-Site: same-origin"
    media_type = environ.get("CONTENT_TYPE", "").partition(";")[0].strip().lower()
    if media_type != "application/json":
        return 403, f"refused: {method} with Content-Type {quote(media_type)}; the page sends application/json"
    return None
