"""Bounded work for strangers: uploads and stroke exports beyond their limits are refused
(503, 413) before they cost anything (docs/serve.md "Bounds", docs/safety.md).  The socket
cap is in test_web_guard.py.  No times are asserted: the tests wait on events."""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from tactilize.data import png_bytes
from tactilize.actuators.recording import RecordingOutput
from tactilize.web import create_app
from tactilize.web import limits
from tactilize.web.limits import MAX_EXPORT_BODY_BYTES, UPLOADS_ADMITTED

LOCAL = "http://127.0.0.1"


@pytest.fixture()
def app():
    return create_app(RecordingOutput(), "paper", warm=False)


def _png() -> bytes:
    return png_bytes((np.arange(64 * 64).reshape(64, 64) % 251).astype(np.uint8), 96.0)


def test_uploads_beyond_the_limit_get_503_and_the_admitted_ones_finish(app):
    state = app.state.tactilize
    started, release = threading.Semaphore(0), threading.Event()
    real = state.add_upload
    running = []

    def slow_add(*args):
        running.append(1)
        started.release()
        release.wait(60)
        out = real(*args)
        running.pop()
        return out

    state.add_upload = slow_add
    answers = []
    with TestClient(app, base_url=LOCAL) as c:
        def post(i):
            answers.append(c.post("/api/textures", files={"file": (f"a{i}.png", _png())}, data={"width_mm": f"{50 + i}"}))

        threads = [threading.Thread(target=post, args=(i,)) for i in range(UPLOADS_ADMITTED)]
        for t in threads:
            t.start()
        assert started.acquire(timeout=60)  # one is analysing, the other waits for its turn
        assert len(running) == 1  # one analysis at a time
        # Wait until every admitted upload is inside (analysing or queued).
        while state.upload_gate.inside < UPLOADS_ADMITTED:
            threading.Event().wait(0.01)
        r = c.post("/api/textures", files={"file": ("late.png", _png())})
        assert r.status_code == 503 and "busy" in r.json()["error"] and "upload" in r.json()["error"]
        release.set()
        for t in threads:
            t.join(60)
        assert sorted(a.status_code for a in answers) == [201] * UPLOADS_ADMITTED
        assert c.get("/api/stats").json()["counters"]["uploads_busy"] == 1
        # Places free again once they are done.
        assert c.post("/api/textures", files={"file": ("again.png", _png())}, data={"width_mm": "70"}).status_code == 201


def test_the_stroke_export_body_is_capped_before_it_is_parsed(app):
    with TestClient(app, base_url=LOCAL) as c:
        big = b"[" + b"[0.0, 1.0, 2.0, 0.5]," * (MAX_EXPORT_BODY_BYTES // 20) + b"[0, 0, 0]]"
        assert len(big) > MAX_EXPORT_BODY_BYTES
        r = c.post("/api/export/stroke", content=big, headers={"content-type": "application/json"})
        assert r.status_code == 413 and "too large" in r.json()["error"]

        # A body sent in pieces without a length is cut off as soon as it is too long.
        def pieces():
            for _ in range(MAX_EXPORT_BODY_BYTES // (1 << 20) + 2):
                yield b" " * (1 << 20)

        r = c.post("/api/export/stroke", content=pieces(), headers={"content-type": "application/json"})
        assert r.status_code == 413
        ok = c.post("/api/export/stroke", json={"texture": "corduroy", "format": "csv",
                                                 "samples": [[i / 240, 5 + i / 24, 10, 0.5] for i in range(50)]})
        assert ok.status_code == 200


def test_stroke_exports_beyond_the_limit_get_503(app):
    from tactilize.web.limits import EXPORTS_ADMITTED

    state = app.state.tactilize
    gate = state.export_gate
    with TestClient(app, base_url=LOCAL) as c:
        gate.inside = EXPORTS_ADMITTED  # as if that many were inside
        r = c.post("/api/export/stroke", json={"texture": "corduroy", "format": "csv", "samples": []})
        assert r.status_code == 503 and "stroke export" in r.json()["error"]
        gate.inside = 0
        r = c.post("/api/export/stroke", json={"texture": "corduroy", "format": "csv",
                                               "samples": [[i / 240, 5 + i / 24, 10, 0.5] for i in range(50)]})
        assert r.status_code == 200 and gate.inside == 0


@pytest.mark.parametrize("width_mm", ["1e-6", "1e-7", "1e-300"])
def test_an_upload_with_a_vanishing_width_is_a_clear_422(app, width_mm):
    with TestClient(app, base_url=LOCAL) as c:
        r = c.post("/api/textures", files={"file": ("tiny.png", _png())}, data={"width_mm": width_mm})
        assert r.status_code == 422 and "tiny.png" in r.json()["error"] and "pixel" in r.json()["error"]


# ------------------------------------------------------------------- one page's flood


@pytest.fixture()
def tight_budget(monkeypatch):
    """A budget of 50 messages per socket, never refilled within a test: the counts are exact, no clock read."""
    monkeypatch.setattr(limits, "MESSAGES_PER_S", 1e-9)
    monkeypatch.setattr(limits, "MESSAGE_BURST", 50)
    return 50


def test_a_flooding_pen_page_is_dropped_and_closed_and_another_page_is_answered(app, tight_budget):
    with TestClient(app, base_url=LOCAL) as c:
        with c.websocket_connect("ws://127.0.0.1/ws") as calm, c.websocket_connect("ws://127.0.0.1/ws") as flood:
            for i in range(4 * tight_budget):
                flood.send_text(json.dumps({"type": "ping", "id": i}))
            for i in range(tight_budget - 10):  # the other page, while the flood is read
                calm.send_text(json.dumps({"type": "ping", "id": i}))
                assert calm.receive_json()["id"] == i
            seen = []
            with pytest.raises(WebSocketDisconnect) as closed:
                for _ in range(4 * tight_budget):  # bounded: the socket closes well before
                    seen.append(flood.receive_json())
            assert closed.value.code == limits.FLOOD_CLOSE_CODE == 1008
            assert [m["id"] for m in seen[:tight_budget]] == list(range(tight_budget))  # the budget: answered
            assert [m["type"] for m in seen[tight_budget:]] == ["error"]  # then told once, then closed
            assert "too many messages" in seen[-1]["message"]
            calm.send_text(json.dumps({"type": "ping", "id": "after"}))
            assert calm.receive_json()["id"] == "after"  # the other page lives on
    counters = app.state.tactilize.counters
    assert counters["messages_dropped"] == tight_budget and counters["sockets_flooding"] == 1


def test_a_flooding_participant_page_is_closed_and_another_is_answered(tmp_path, tight_budget):
    from tactilize.experiments.web import create_experiment_app

    from _experiment_socket import open_session

    with TestClient(create_experiment_app("alpha-law", str(tmp_path / "flood.sqlite3")), base_url=LOCAL) as c:
        flooder, _ = open_session(c, "F1")
        other, _ = open_session(c, "F2")
        with c.websocket_connect(f"ws://127.0.0.1/experiment/ws/{other}") as calm, \
                c.websocket_connect(f"ws://127.0.0.1/experiment/ws/{flooder}") as flood:
            for i in range(4 * tight_budget):
                flood.send_text(json.dumps({"type": "ping"}))
            for _ in range(tight_budget - 10):
                calm.send_text(json.dumps({"type": "ping"}))
                assert calm.receive_json()["type"] == "pong"
            seen = []
            with pytest.raises(WebSocketDisconnect) as closed:
                for _ in range(4 * tight_budget):
                    seen.append(flood.receive_json())
            assert closed.value.code == 1008
            assert len(seen) <= tight_budget + 1 and all(m["type"] in ("pong", "error") for m in seen)
            calm.send_text(json.dumps({"type": "ping"}))
            assert calm.receive_json()["type"] == "pong"
