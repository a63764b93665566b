"""Running the pen page: ``tactilize serve`` calls :func:`serve`.

The server binds to loopback unless another host is given explicitly; the
socket is bound *before* uvicorn starts, so the printed address is the real one
(port 0 picks a free port) and a busy port is a one-line error, not a traceback.
"""

from __future__ import annotations

import os
import socket
import sys
import threading
import webbrowser
from typing import Any, Callable, Iterable

from ..errors import TactilizeError
from ..http import is_loopback

#: The pen's default profile, as every command's: the surface rendering, a pulse per
#: bump under the stylus tip (docs/surfaces.md).
DEFAULT_PROFILE = "surface"
#: CPython GIL switch interval [s] while serving (see serve()); the bench uses the same.
SWITCH_INTERVAL_S = 0.0005

__all__ = ["DEFAULT_PROFILE", "SWITCH_INTERVAL_S", "serve", "server_config", "is_loopback", "bind_socket",
           "display_available"]


def bind_socket(host: str, port: int) -> socket.socket:
    """A listening TCP socket on host:port (port 0: any free port).

    Raises
    ------
    TactilizeError
        The address is in use, not available here, or the host is unknown.
    """
    try:
        infos = socket.getaddrinfo(host.strip("[]"), port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as exc:
        raise TactilizeError(f"--host {host}", f"unknown host ({exc.strerror})") from None
    family, _, _, _, addr = infos[0]
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    # No Nagle: a drive is a small write that often follows another (a wire trace);
    # held back until the client's delayed ACK, it arrived about 40 ms late, once
    # every trace period.  Connections accepted from this socket inherit the option.
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    try:
        sock.bind(addr)
        sock.listen(128)
    except OSError as exc:
        sock.close()
        raise TactilizeError(f"{host}:{port}", f"cannot listen ({exc.strerror or exc})") from None
    sock.set_inheritable(True)
    return sock


def _head_deadline_protocol(header_timeout_s: float) -> type:
    """uvicorn's HTTP protocol, with a deadline for each request's head.

    uvicorn waits for a request line and headers as long as the client likes, so
    a connection that never finishes its head would stay open for good.  Here
    the head must be in within ``header_timeout_s`` [s] of the connection's
    opening or its previous response's end; else 408, and the connection closes.
    """
    from uvicorn.protocols.http.auto import AutoHTTPProtocol

    body = b'{"error": "request headers too slow"}'
    late = (b"HTTP/1.1 408 Request Timeout\r\ncontent-type: application/json\r\nconnection: close\r\n"
            b"content-length: " + str(len(body)).encode() + b"\r\n\r\n" + body)

    class HeadDeadline(AutoHTTPProtocol):  # type: ignore[misc, valid-type]
        _head_timer: Any = None

        def connection_made(self, transport: Any) -> None:
            super().connection_made(transport)
            self._arm()

        def on_response_complete(self) -> None:
            super().on_response_complete()
            self._arm()

        def connection_lost(self, exc: Exception | None) -> None:
            if self._head_timer is not None:
                self._head_timer.cancel()
            super().connection_lost(exc)

        def _arm(self) -> None:
            if self._head_timer is not None:
                self._head_timer.cancel()
            self._head_timer = self.loop.call_later(header_timeout_s, self._head_late)

        def _head_late(self) -> None:
            self._head_timer = None
            t = self.transport
            if t.is_closing() or t.get_protocol() is not self:  # closed, or a WebSocket now
                return
            if self.cycle is not None and not self.cycle.response_complete:  # its head came: being answered
                return
            t.write(late)
            t.close()

    return HeadDeadline


def server_config(app: Any, host: str, port: int, *, ssl_files: tuple[str, str] | None = None,
                  log_level: str = "warning", header_timeout_s: float | None = None) -> Any:
    """The uvicorn configuration every server of tactilize runs with.

    Parameters
    ----------
    app : ASGI app
        What to serve (its guard bounds the sockets and requests at once).
    host, port : str, int
        The address bound (the socket itself is given to ``uvicorn.Server.run``).
    ssl_files : (cert, key), optional
        PEM files for HTTPS.
    log_level : str
        uvicorn's log level.
    header_timeout_s : float, optional
        Time a request's head may take [s]; :data:`.limits.HEADER_TIMEOUT_S` by default.

    Returns
    -------
    uvicorn.Config
    """
    import uvicorn

    from .limits import HEADER_TIMEOUT_S

    return uvicorn.Config(
        app,
        host=host,
        port=port,
        http=_head_deadline_protocol(HEADER_TIMEOUT_S if header_timeout_s is None else header_timeout_s),
        ssl_certfile=ssl_files[0] if ssl_files else None,
        ssl_keyfile=ssl_files[1] if ssl_files else None,
        log_level=log_level,
        ws_max_size=1024 * 1024,  # the protocol's messages are far smaller
        # Compression costs ~0.1 ms per message each way and saves nothing on
        # loopback, where the page almost always is.
        ws_per_message_deflate=False,
        ws_ping_interval=20.0,
        ws_ping_timeout=20.0,
        lifespan="on",
        # No limit_concurrency: uvicorn counts a connection still sending its
        # head against it, so slow clients could fill it.  The guard bounds the
        # sockets and the requests being answered (web/guard.py), the head
        # deadline above the rest.
    )


def display_available() -> bool:
    """Can a browser window be opened here?  (Not on a headless server.)"""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def serve(
    host: str = "127.0.0.1",
    port: int = 8765,
    output: str = "simulated",
    profile: str | None = None,
    open_browser: bool | None = None,
    *,
    extra_routers: Iterable[Any] = (),
    echo: Callable[[str], None] = print,
    warn: Callable[[str], None] = lambda s: print(s, file=sys.stderr),
    log_level: str = "warning",
    extra_hosts: Iterable[str] = (),
    max_sockets: int | None = None,
    lan: bool = False,
    https: bool = False,
    open_path: str = "",
    material: Any = None,
) -> None:
    """Serve the tactile pen page until interrupted.

    Parameters
    ----------
    host : str
        Address to bind; loopback unless the caller was given another explicitly.
    port : int
        TCP port; 0 picks a free one.
    output : str
        Output spec for :func:`tactilize.actuators.factory.open_output`.
    profile : str, optional
        Preset name or TOML file; by default :data:`DEFAULT_PROFILE` (the paper's
        laws stay one click away on the page).
    open_browser : bool, optional
        Open the page in a browser; by default only when a display exists.
    open_path : str
        The page to open, below the server's address (the pen page when empty).
    extra_routers : iterable of APIRouter
        Mounted into the app.
    extra_hosts : iterable of str
        Names or addresses the page may also be reached at, besides loopback and
        ``host`` (:func:`.guard.accepted_hosts`: the one set every check uses).
    max_sockets : int, optional
        WebSockets open at once, at most (:data:`.guard.DEFAULT_MAX_SOCKETS`).
    lan : bool
        Bind this machine's address on the local network (or ``host``, when it
        is one) so a phone can reach the page; the URL to type is printed with
        a QR code (:mod:`.lan`).
    https : bool
        Serve HTTPS with a self-signed certificate made and kept by :mod:`.tls`
        (the page's audio output and raw pointer updates need it off loopback).
    material : MaterialChoice or str, optional
        What the built-in pictures and uploads are rendered as (``--material``,
        ``--relief-mm``); the page's picker may pick another.  Picture only by default.
    """
    import uvicorn

    from ..actuators.factory import open_output
    from ..mapping import Profile
    from .app import create_app
    from .guard import DEFAULT_MAX_SOCKETS, accepted_hosts

    prof = Profile.resolve(DEFAULT_PROFILE if profile is None else profile)  # bad profiles fail before anything opens
    if lan:
        from .lan import lan_host

        # From here on ``host`` is the address bound and typed on the phone: the
        # one the server's host and origin checks must accept.
        host = lan_host(None if is_loopback(host) else host)
    ssl_files: tuple[str, str] | None = None
    if https:
        from .tls import certificate_for

        cert, key = certificate_for([host])
        ssl_files = (str(cert), str(key))
    sock = bind_socket(host, port)
    try:
        try:
            out = open_output(output)
        except ImportError as exc:
            if output.strip().lower() != "simulated":
                raise TactilizeError(f"--output {output}", f"not available in this installation ({exc})") from None
            # A partial build without the wire model: still serve the page.
            from ..actuators.recording import RecordingOutput

            warn(f"tactilize: warning: the simulated wire is not available ({exc}); drives are only recorded")
            out = RecordingOutput()
            output = "recorder (no simulated wire)"
    except BaseException:
        sock.close()
        raise
    try:
        max_sockets = DEFAULT_MAX_SOCKETS if max_sockets is None else max_sockets
        # A simulated wire is no device: every page gets its own (web/ownership.py).
        per_page = (lambda: open_output(output)) if output.strip().lower() == "simulated" else None
        app = create_app(out, prof, output_name=output, extra_routers=extra_routers, close_output=True,
                         hosts=accepted_hosts(host, extra_hosts), max_sockets=max_sockets, page_outputs=per_page,
                         material=material)
        from .lan import context_notes, page_url, qr_text

        bound_host, bound_port = sock.getsockname()[:2]
        url = page_url(bound_host, bound_port, secure=https)
        if not is_loopback(host):
            warn(
                f"tactilize: warning: serving on {host}, reachable from other machines on the network; "
                "anyone who can reach it can drive the actuators"
            )
        config = server_config(app, bound_host, bound_port, ssl_files=ssl_files, log_level=log_level)
        server = uvicorn.Server(config)
        # The simulated wire runs on a thread; with CPython's default 5 ms GIL
        # switch interval a pen batch could wait up to 5 ms for the event loop.
        # 0.5 ms keeps the wait under the 1 ms server-side budget.  This process
        # only serves, so the global setting harms nothing else.
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        echo(f"tactilize: serving the tactile pen at {url} (output {output}, profile {prof.name}); Ctrl-C to stop")
        if lan:
            echo(f"tactilize: on a phone on the same network, open {url} or scan:")
            echo(qr_text(url))
        if not is_loopback(host):
            for line in context_notes(secure=https):
                echo(f"tactilize: {line}")
        if https and ssl_files is not None:
            echo(f"tactilize: HTTPS with a self-signed certificate ({ssl_files[0]}): the browser warns once; see docs/serve.md")
        if open_browser is None:
            open_browser = display_available()
        if open_browser:
            threading.Timer(0.5, lambda: webbrowser.open(url + open_path.lstrip("/"))).start()
        server.run(sockets=[sock])
    finally:
        sock.close()
        try:
            out.close()
        except Exception:
            pass
