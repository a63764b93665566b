"""Slow clients starve no one: a live uvicorn server on 127.0.0.1, real sockets, timeouts shortened for the test
(docs/serve.md "Bounds", docs/safety.md "Who may touch what").  No times are asserted; every loop is bounded in
count and in time."""

from __future__ import annotations

import contextlib
import json
import socket
import threading
import time

import httpx
import numpy as np
import pytest
import uvicorn

from tactilize.actuators.recording import RecordingOutput
from tactilize.data import png_bytes
from tactilize.web import create_app, limits
from tactilize.web.serve import bind_socket, server_config

#: Longest any single wait of these tests may take [s] (a loaded machine), never reached when all is well.
PATIENCE_S = 60.0


@contextlib.contextmanager
def live(app, header_timeout_s):
    """``app`` served by uvicorn, configured as ``tactilize serve`` configures it; yields the port."""
    sock = bind_socket("127.0.0.1", 0)
    port = sock.getsockname()[1]
    server = uvicorn.Server(server_config(app, "127.0.0.1", port, header_timeout_s=header_timeout_s))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    deadline = time.monotonic() + PATIENCE_S
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.02)
    assert server.started
    try:
        yield port
    finally:
        server.should_exit = True
        thread.join(PATIENCE_S)
        sock.close()


def _half_sent(port: int, text: bytes) -> socket.socket:
    s = socket.create_connection(("127.0.0.1", port), timeout=PATIENCE_S)
    s.sendall(text)
    return s


def _answer(s: socket.socket) -> bytes:
    """Everything the server sends until it closes (bounded by the socket's timeout and a size)."""
    data = b""
    while len(data) < 65536:
        chunk = s.recv(4096)
        if not chunk:
            break
        data += chunk
    return data


def _png() -> bytes:
    return png_bytes((np.arange(64 * 64).reshape(64, 64) % 251).astype(np.uint8), 96.0)


def _until(cond, what):
    deadline = time.monotonic() + PATIENCE_S
    while not cond():
        assert time.monotonic() < deadline, what
        time.sleep(0.01)


@pytest.fixture()
def app():
    return create_app(RecordingOutput(), "paper", warm=False)


def test_half_sent_request_lines_hold_no_place_the_page_needs(app):
    with live(app, header_timeout_s=PATIENCE_S) as port, contextlib.ExitStack() as stack:
        for _ in range(100):
            stack.enter_context(_half_sent(port, b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n"))
        r = httpx.get(f"http://127.0.0.1:{port}/", timeout=PATIENCE_S)
        assert r.status_code == 200 and "text/html" in r.headers["content-type"]


def test_a_request_head_that_never_ends_gets_408_and_is_closed(app):
    from websockets.sync.client import connect

    with live(app, header_timeout_s=0.5) as port:
        with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=PATIENCE_S) as ws:
            slow = [_half_sent(port, b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n"), _half_sent(port, b"GE")]
            idle = socket.create_connection(("127.0.0.1", port), timeout=PATIENCE_S)
            for s in [*slow, idle]:
                with s:
                    answer = _answer(s)  # returns once the server closes
                    assert answer.startswith(b"HTTP/1.1 408 ") and b"too slow" in answer, answer[:200]
            # Past the deadline: a WebSocket (its head came long ago) and a keep-alive request are untouched.
            ws.send(json.dumps({"type": "ping", "id": 3}))
            assert json.loads(ws.recv(timeout=PATIENCE_S))["id"] == 3
            with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=PATIENCE_S) as c:
                assert c.get("/api/config").status_code == 200
                assert c.get("/api/config").status_code == 200


def test_trickling_bodies_get_408_release_their_gates_and_others_are_served_meanwhile(app, monkeypatch):
    monkeypatch.setattr(limits, "BODY_GRACE_S", 3.0)
    monkeypatch.setattr(limits, "BODY_MIN_BYTES_S", 1000)
    state = app.state.tactilize
    head = ("POST {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: {kind}\r\nContent-Length: 100000\r\n\r\n")
    with live(app, header_timeout_s=PATIENCE_S) as port:
        slow = [_half_sent(port, head.format(path=p, kind=k).encode() + b"-")
                for p, k in [("/api/textures", "multipart/form-data; boundary=x")] * 2
                + [("/api/export/stroke", "application/json")] * 2]
        try:
            _until(lambda: state.upload_gate.inside == 2 and state.export_gate.inside == 2, "the slow ones inside")
            # While two slow uploads and two slow exports are inside, others are served.
            with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=PATIENCE_S) as c:
                up = c.post("/api/textures", files={"file": ("a.png", _png())}, data={"width_mm": "50"})
                assert up.status_code == 201, up.text
                ex = c.post("/api/export/stroke", json={"texture": "corduroy", "format": "csv",
                                                        "samples": [[i / 240, 5 + i / 24, 10, 0.5] for i in range(50)]})
                assert ex.status_code == 200, ex.text
            # The slow ones keep trickling, a byte now and then, until the server cuts them off.
            answers = [b""] * len(slow)
            for _ in range(int(PATIENCE_S / 0.1)):
                for i, s in enumerate(slow):
                    if not answers[i]:
                        try:
                            s.sendall(b"-")
                            s.setblocking(False)
                            answers[i] = s.recv(4096)
                        except (BlockingIOError, InterruptedError):
                            pass
                        except OSError:  # closed by the server after its answer
                            answers[i] = b"closed"
                        finally:
                            s.setblocking(True)
                if all(answers):
                    break
                time.sleep(0.1)
            for a in answers:
                assert a.startswith(b"HTTP/1.1 408 ") and b"too slow" in a, a[:300]
        finally:
            for s in slow:
                s.close()
        _until(lambda: state.upload_gate.inside == 0 and state.export_gate.inside == 0, "the gates freed")
