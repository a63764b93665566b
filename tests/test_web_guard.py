"""Who may touch the server: forged Host and Origin headers, DNS rebinding, the socket cap
(docs/safety.md, "Who may touch what")."""

from __future__ import annotations

import re
import socket
import subprocess
import sys

import pytest
from fastapi.testclient import TestClient
from starlette.testclient import WebSocketDenialResponse

from tactilize.actuators.recording import RecordingOutput
from tactilize.web import create_app
from tactilize.web.guard import accepted_hosts, host_name

LOCAL = "http://127.0.0.1"
EVIL = "http://evil.example"


def test_the_accepted_hosts_are_loopback_and_the_bind_address_and_what_an_option_adds():
    assert accepted_hosts("127.0.0.1") == {"localhost", "127.0.0.1", "::1"}
    lan = accepted_hosts("192.0.2.7")
    assert "192.0.2.7" in lan and "localhost" in lan and "evil.example" not in lan
    assert "198.51.100.3" in accepted_hosts("127.0.0.1", ["198.51.100.3"])  # e.g. a LAN option
    assert accepted_hosts("[::1]") == accepted_hosts("::1")
    assert host_name("[::1]:8765") == "::1" and host_name("LocalHost.:80") == "localhost"
    assert host_name("evil.example:8765") == "evil.example"
    assert host_name("::1") == "::1" and host_name("[fe80::1%eth0]:80") == "fe80::1%eth0" and host_name("") == ""


@pytest.mark.parametrize("host", ["127.0.0.1:8765@evil.example", "localhost@evil.example", "[::1", "[::1]evil",
                                  "127.0.0.1:80:81", "127.0.0.1:x", "127.0.0.1/evil", "evil.example#127.0.0.1",
                                  "[::1]:8765@evil.example"])
def test_a_malformed_host_is_not_loopback(pen, host):
    assert host_name(host) not in accepted_hosts("127.0.0.1"), host
    c, _ = pen
    assert c.get("/api/config", headers={"Host": host}).status_code == 421


@pytest.fixture()
def pen():
    out = RecordingOutput()
    with TestClient(create_app(out, "paper", warm=False), base_url=LOCAL) as c:
        yield c, out


def test_a_rebinding_host_is_refused_on_every_route_and_socket(pen):
    c, _ = pen
    assert c.get("/api/config").status_code == 200
    assert c.get("/api/config", headers={"Host": "127.0.0.1:8765"}).status_code == 200
    assert c.get("/api/config", headers={"Host": "localhost:8765"}).status_code == 200
    # evil.example resolved to 127.0.0.1: the browser sends its own name, and its own
    # origin, so the request looks same-origin to it.
    r = c.get("/api/config", headers={"Host": "evil.example:8765"})
    assert r.status_code == 421 and "evil.example" in r.json()["error"]
    with pytest.raises(WebSocketDenialResponse) as denied:
        with c.websocket_connect("ws://evil.example:8765/ws", headers={"Origin": "http://evil.example:8765"}):
            pass
    assert denied.value.status_code == 421


def test_a_page_on_another_site_cannot_open_the_pen_socket(pen):
    c, out = pen
    for origin in (EVIL, "http://127.0.0.1.evil.example", "null", "file://"):
        with pytest.raises(WebSocketDenialResponse) as denied:
            with c.websocket_connect("ws://127.0.0.1/ws", headers={"Origin": origin}):
                pass
        assert denied.value.status_code == 403
    assert out.applied == []
    # The page itself (its own origin) and clients that are not browsers (no Origin) connect.
    for headers in ({"Origin": LOCAL}, {}):
        with c.websocket_connect("ws://127.0.0.1/ws", headers=headers) as ws:
            ws.send_json({"type": "ping", "id": 1})
            assert ws.receive_json()["type"] == "pong"


def test_state_changing_routes_refuse_another_sites_origin(pen):
    c, _ = pen
    cross = {"Origin": EVIL}
    r = c.post("/api/textures", files={"file": ("a.png", b"x")}, headers=cross)
    assert r.status_code == 403 and "Origin" in r.json()["error"]
    assert c.post("/api/export/stroke", json={}, headers=cross).status_code == 403
    # The same requests from the page's own origin reach their handler (and its own refusal).
    assert c.post("/api/textures", files={"file": ("a.png", b"x")}, headers={"Origin": LOCAL}).status_code == 415
    # Reading is not state-changing: a cross-site GET is answered (the browser hides it from the page).
    assert c.get("/api/textures/nope.png", headers=cross).status_code == 404


def test_the_address_given_to_host_is_accepted_so_a_phone_connects():
    app = create_app(RecordingOutput(), "paper", warm=False, hosts=accepted_hosts("192.0.2.7"))
    with TestClient(app, base_url="http://192.0.2.7:8765") as c:
        assert c.get("/api/config").status_code == 200
        with c.websocket_connect("ws://192.0.2.7:8765/ws", headers={"Origin": "http://192.0.2.7:8765"}) as ws:
            ws.send_json({"type": "ping", "id": 1})
            assert ws.receive_json()["type"] == "pong"
        assert c.get("/api/config", headers={"Host": "evil.example"}).status_code == 421


def test_the_experiment_refuses_rebinding_cross_site_answers_and_sockets(tmp_path):
    from tactilize.experiments.web import create_experiment_app

    app = create_experiment_app("alpha-law", str(tmp_path / "x.db"), admin_token="secret")
    api = "/experiment/api"
    with TestClient(app, base_url=LOCAL) as c:
        token = c.post(f"{api}/sessions", json={"participant_id": "P1", "consent": True}).json()["session"]
        # DNS rebinding cannot read the export, even with the token guessed right.
        r = c.get(f"{api}/admin/export.csv?token=secret", headers={"Host": "evil.example"})
        assert r.status_code == 421
        r = c.post(f"{api}/sessions/{token}/answers", json={"trial": 0, "ratings": {}}, headers={"Origin": EVIL})
        assert r.status_code == 403
        with pytest.raises(WebSocketDenialResponse):
            with c.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}", headers={"Origin": EVIL}):
                pass
        # Resuming needs more than the ID, on loopback too.
        assert c.post(f"{api}/resume", json={"participant_id": "P1"}).status_code == 401
        assert c.post(f"{api}/resume", json={"participant_id": "P1", "token": "secret"}).json()["session"] == token


def test_sockets_beyond_the_cap_are_refused_with_503():
    app = create_app(RecordingOutput(), "paper", warm=False, max_sockets=2)
    with TestClient(app, base_url=LOCAL) as c:
        with c.websocket_connect("ws://127.0.0.1/ws"), c.websocket_connect("ws://127.0.0.1/ws"):
            with pytest.raises(WebSocketDenialResponse) as denied:
                with c.websocket_connect("ws://127.0.0.1/ws"):
                    pass
            assert denied.value.status_code == 503
            assert app.state.guard.refused["sockets"] == 1
        # Closed sockets free their places.
        with c.websocket_connect("ws://127.0.0.1/ws") as ws:
            ws.send_json({"type": "ping", "id": 1})
            assert ws.receive_json()["type"] == "pong"


def test_a_live_server_refuses_forged_origins_and_sockets_beyond_max_sockets():
    """uvicorn and a real WebSocket client (websockets): the refusals reach the wire."""
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    proc = subprocess.Popen([sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--port", "0",
                             "--max-sockets", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        m = re.search(r"http://127\.0\.0\.1:(\d+)/", proc.stdout.readline())
        assert m
        url = f"ws://127.0.0.1:{m.group(1)}/ws"
        with pytest.raises(InvalidStatus) as bad:
            connect(url, origin=EVIL, open_timeout=30)
        assert bad.value.response.status_code == 403
        with pytest.raises(InvalidStatus) as bad:
            # DNS rebinding: the name is the attacker's, the address is loopback.
            rebound = socket.create_connection(("127.0.0.1", int(m.group(1))))
            connect(f"ws://evil.example:{m.group(1)}/ws", sock=rebound, open_timeout=30)
        assert bad.value.response.status_code == 421
        with connect(url, origin=f"http://127.0.0.1:{m.group(1)}", open_timeout=30) as ws:
            with pytest.raises(InvalidStatus) as bad:
                connect(url, open_timeout=30)
            assert bad.value.response.status_code == 503
            ws.send('{"type": "ping", "id": 7}')
            assert '"pong"' in ws.recv(timeout=30)
    finally:
        proc.terminate()
        proc.communicate(timeout=30)


def test_http_requests_beyond_the_cap_are_refused_with_503(pen):
    c, _ = pen
    guard = c.app.state.guard
    guard.requests = guard.max_requests  # as if that many were being answered
    try:
        r = c.get("/api/config")
        assert r.status_code == 503 and "too many requests" in r.json()["error"] and guard.refused["requests"] == 1
    finally:
        guard.requests = 0
    assert c.get("/api/config").status_code == 200 and guard.requests == 0
