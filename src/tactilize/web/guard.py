"""Who may talk to the server: the Host and Origin checks, and the socket cap.

A page on another web site can open a WebSocket or post a form to any address
the user's browser reaches, loopback included (cross-site WebSocket hijacking),
and through DNS rebinding it can even read the answers: the attacker's own name
is made to resolve to 127.0.0.1, so the browser treats the server as the
attacker's origin.  Two checks close both doors (docs/safety.md, "Who may
touch what"):

- the ``Host`` header of every request and socket must name the server as it
  was started: a loopback name, or the address given to ``--host``
  (:func:`accepted_hosts`); a rebinding page's ``Host`` is its own name;
- a browser's ``Origin``, sent on every WebSocket and every cross-site POST,
  must be the server itself (the ``Host`` it was sent to), on every socket and
  every state-changing request (any method but GET, HEAD, OPTIONS).

Clients that send no ``Origin`` (curl, scripts, the tests) are not browsers and
cannot be driven by a web site, so they pass the Origin check.

`install` puts :class:`RequestGuard`, a plain ASGI middleware, in front of an app, so it covers every route and
socket of the app it wraps, the ones other packages mount included.
"""

from __future__ import annotations

import logging
import re
import socket
from typing import Any, Iterable, NamedTuple
from urllib.parse import urlsplit

from .limits import MAX_REQUESTS

__all__ = ["LOOPBACK_NAMES", "DEFAULT_MAX_SOCKETS", "accepted_hosts", "host_name", "Guard", "RequestGuard", "install"]

log = logging.getLogger("tactilize.web")

#: Names a browser on this machine uses for a server on loopback.
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
#: WebSockets open at once, at most, by default (``tactilize serve --max-sockets``).
DEFAULT_MAX_SOCKETS = 32
_SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
_WILDCARDS = frozenset({"", "0.0.0.0", "::"})


#: A Host header: a name or IPv4 address, or an IPv6 address in brackets, then
#: an optional port of digits (RFC 9110, section 7.2; RFC 3986, section 3.2.2).
_HOST_HEADER = re.compile(r"(?:(?P<name>[a-z0-9._~%-]*)|\[(?P<ipv6>[0-9a-f:.]+(?:%[a-z0-9._~-]+)?)\])(?::[0-9]*)?")
#: An IPv6 address given bare, as ``--host ::1`` may be.
_BARE_IPV6 = re.compile(r"[0-9a-f:.]+(?:%[a-z0-9._~-]+)?")


def host_name(value: str) -> str:
    """The host part of a ``Host`` header or ``--host`` value: lower case, no port,
    IPv6 without brackets (``"[::1]:8765"`` -> ``"::1"``).

    A value that is no host (``"127.0.0.1:80@evil.example"``, ``"[::1"``) comes
    back whole, so it matches none of the names a server accepts.
    """
    v = value.strip().lower()
    m = _HOST_HEADER.fullmatch(v)
    if m is not None:
        v = m.group("ipv6") or m.group("name")
    elif v.count(":") < 2 or _BARE_IPV6.fullmatch(v) is None:
        return v
    return v.rstrip(".")  # "localhost." is localhost (a fully qualified name)


def accepted_hosts(bind_host: str, extra: Iterable[str] = ()) -> frozenset[str]:
    """The host names a server bound to ``bind_host`` answers to.

    Parameters
    ----------
    bind_host : str
        The address given to ``--host`` (a name or an IP, IPv6 with or without
        brackets).  A wildcard (``0.0.0.0``, ``::``) adds this machine's name and
        every address of its interfaces.
    extra : iterable of str
        More names or addresses to accept (an option that binds another
        interface, e.g. the LAN address a phone connects to, adds it here).

    Returns
    -------
    frozenset of str
        Lower-case host names without port; always the loopback names.
    """
    names = set(LOOPBACK_NAMES)
    for h in (bind_host, *extra):
        h = host_name(h)
        if h in _WILDCARDS:
            names |= _this_machine()
        else:
            names.add(h)
    return frozenset(names)


def _this_machine() -> set[str]:
    names = {socket.gethostname().lower()}
    try:
        names.add(socket.getfqdn().lower())
        names |= {str(info[4][0]).lower() for info in socket.getaddrinfo(socket.gethostname(), None)}
    except OSError:
        pass
    try:
        import psutil  # present with the batch extra; without it, the name's addresses only

        for addrs in psutil.net_if_addrs().values():
            names |= {a.address.split("%")[0].lower() for a in addrs if a.family in (socket.AF_INET, socket.AF_INET6)}
    except ImportError:
        pass
    return {n for n in names if n}


def _refusal(scope: dict[str, Any], hosts: frozenset[str]) -> tuple[int, str] | None:
    """(status, reason) when the request must be refused, else None."""
    headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", ())}
    host = headers.get("host", "")
    if host_name(host) not in hosts:
        return 421, (f"Host {host!r} is not this server (it answers to {', '.join(sorted(hosts))}); "
                     "a page on another site may not reach it")
    origin = headers.get("origin")
    if origin is None or (scope["type"] == "http" and scope.get("method", "GET") in _SAFE_METHODS):
        return None
    parts = urlsplit(origin.strip().lower())
    if parts.scheme not in ("http", "https") or parts.netloc != host.strip().lower():
        return 403, f"Origin {origin!r} is not this server: pages on other sites may not use it"
    return None


class Guard:
    """What the checks accept, and what they have seen (shared by the middleware
    and whoever reports: ``app.state.guard``).

    Parameters
    ----------
    hosts : iterable of str
        What :func:`accepted_hosts` returned for the server's bind address.
    max_sockets : int
        WebSockets open at once, at most; one more is refused with HTTP 503
        before it is accepted (no session, no task is started for it).
    max_requests : int
        HTTP requests answered at once, at most (:data:`.limits.MAX_REQUESTS`);
        one more is refused with 503.
    """

    def __init__(self, hosts: Iterable[str], max_sockets: int = DEFAULT_MAX_SOCKETS, max_requests: int = MAX_REQUESTS) -> None:
        for name, n in (("max_sockets", max_sockets), ("max_requests", max_requests)):
            if isinstance(n, bool) or int(n) < 1:
                raise ValueError(f"{name} must be at least 1, got {n}")
        self.hosts = frozenset(host_name(h) for h in hosts)
        self.max_sockets = int(max_sockets)
        self.max_requests = int(max_requests)
        #: WebSockets open now
        self.sockets = 0
        #: HTTP requests being answered now
        self.requests = 0
        #: refusals so far, by kind
        self.refused: dict[str, int] = {"host": 0, "origin": 0, "sockets": 0, "requests": 0}


class _Cap(NamedTuple):
    """How many of one kind of connection a :class:`Guard` admits at once."""

    counter: str  # the Guard's attribute counting those open now (and its refusals' kind)
    limit: str  # the Guard's attribute holding the most it admits
    too_many: str  # what a refusal says...
    retry: str  # ...and when to try again


#: One cap for each kind of ASGI connection.
_CAPS = {
    "http": _Cap("requests", "max_requests", "too many requests at once", "in a moment"),
    "websocket": _Cap("sockets", "max_sockets", "too many open connections", "later"),
}


class RequestGuard:
    """ASGI middleware: refuse requests and sockets that fail the checks above,
    WebSockets beyond ``guard.max_sockets`` open at once and HTTP requests
    beyond ``guard.max_requests``.

    A refused HTTP request gets its status and ``{"error": reason}``; a refused
    socket gets the same as the HTTP answer to its handshake where the server
    supports that (uvicorn, Starlette's test client), else close code 1008
    (policy) or 1013 (try again later).
    """

    def __init__(self, app: Any, guard: Guard) -> None:
        self.app = app
        self.guard = guard

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        g = self.guard
        if scope["type"] not in _CAPS:  # lifespan: nothing to check
            await self.app(scope, receive, send)
            return
        bad = _refusal(scope, g.hosts)
        if bad is not None:
            g.refused["host" if bad[0] == 421 else "origin"] += 1
            log.warning("refused %s %s: %s", scope["type"], scope.get("path", ""), bad[1])
            await _refuse(scope, receive, send, *bad)
            return
        cap = _CAPS[scope["type"]]
        n, limit = getattr(g, cap.counter), getattr(g, cap.limit)
        if n >= limit:
            g.refused[cap.counter] += 1
            await _refuse(scope, receive, send, 503, f"{cap.too_many} ({n}, limit {limit}); try again {cap.retry}")
            return
        setattr(g, cap.counter, n + 1)
        try:
            await self.app(scope, receive, send)
        finally:
            setattr(g, cap.counter, getattr(g, cap.counter) - 1)


def install(app: Any, hosts: Iterable[str] | None = None, max_sockets: int = DEFAULT_MAX_SOCKETS) -> Guard:
    """Put the checks in front of ``app`` (a Starlette/FastAPI app); returns the
    :class:`Guard`, also kept as ``app.state.guard``.  ``hosts`` defaults to
    ``accepted_hosts("127.0.0.1")``: the loopback names."""
    guard = Guard(accepted_hosts("127.0.0.1") if hosts is None else hosts, max_sockets)
    app.add_middleware(RequestGuard, guard=guard)
    app.state.guard = guard
    return guard


async def _refuse(scope: dict[str, Any], receive: Any, send: Any, status: int, reason: str) -> None:
    import json

    body = json.dumps({"error": reason}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    if scope["type"] == "http":
        await send({"type": "http.response.start", "status": status, "headers": headers})
        await send({"type": "http.response.body", "body": body})
        return
    msg = await receive()  # websocket.connect
    if msg.get("type") != "websocket.connect":
        return
    if "websocket.http.response" in scope.get("extensions", {}):
        await send({"type": "websocket.http.response.start", "status": status, "headers": headers})
        await send({"type": "websocket.http.response.body", "body": body})
    else:
        await send({"type": "websocket.close", "code": 1013 if status == 503 else 1008, "reason": reason[:120]})
