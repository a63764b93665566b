"""The web app in-process: routes, uploads, the WebSocket protocol and its bad cases (the CLI: test_web_serve.py)."""

from __future__ import annotations

import io
import json
import time

import numpy as np
import pytest
from fastapi import APIRouter
from fastapi.testclient import TestClient

from tactilize.mapping import Drive, Profile
from tactilize.data import png_bytes
from tactilize.actuators.base import OutputBase
from tactilize.web import create_app
from tactilize.web import session as session_mod
from tactilize.web.rows import DEFAULT_M_PER_CSS_PX, sample_error, samples_from_css


class FakeOutput(OutputBase):
    """Records what the server applies; halves nothing, clamps nothing."""

    channels = 2
    #: settable here (OutputBase's is read-only): tests raise a fault by hand
    fault: str | None = None

    def __init__(self):
        self.applied: list[list[Drive]] = []
        self.stops = 0
        self.closed = False

    def apply(self, channels):
        drives = list(channels)
        self.applied.append(drives)
        return drives

    def stop(self):
        self.stops += 1

    def close(self):
        self.closed = True


@pytest.fixture(scope="module")
def output():
    return FakeOutput()


@pytest.fixture(scope="module")
def client(output):
    router = APIRouter()

    @router.get("/api/extra-ping")
    def extra():
        return {"ok": True}

    app = create_app(output, "paper", output_name="fake", extra_routers=[router])
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


def stroke_rows(v_mm_s, n=20, dt_ms=5.0, x0=20.0, y0=30.0, t0=1000.0, mm_per_px=DEFAULT_M_PER_CSS_PX * 1e3):
    """A horizontal stroke from (x0, y0) [CSS px] as the pages send it: millimetres by the page's scale."""
    v_px_ms = v_mm_s / mm_per_px / 1e3
    return [[t0 + i * dt_ms, (x0 + v_px_ms * i * dt_ms) * mm_per_px, y0 * mm_per_px, 0.5, 0.0, 0.0] for i in range(n)]


def recv_type(ws, kind, limit=50):
    for _ in range(limit):
        m = ws.receive_json()
        if m["type"] == kind:
            return m
    raise AssertionError(f"no {kind} message")


def hello(ws, texture="corduroy", **kw):
    ws.send_text(json.dumps({"type": "hello", "texture": texture, **kw}))
    return recv_type(ws, "ready")


# ------------------------------------------------------------------- routes


def test_page_has_test_ids_and_modules(client):
    r = client.get("/")
    assert r.status_code == 200 and "text/html" in r.headers["content-type"]
    for tid in ("surface", "drive-frequency", "drive-pulse-width", "drive-duty", "drive-amplitude", "drive-speed", "audio-toggle"):
        assert f'data-testid="{tid}"' in r.text
    assert 'type="module"' in r.text
    for mod in ("app.js", "pen-input.js", "plot.js", "trail.js", "drawing.js", "draw-worker.js", "audio.js", "pulse-worklet.js",
                "calibrate.js", "style.css"):
        s = client.get(f"/static/{mod}")
        assert s.status_code == 200, mod
    assert "javascript" in client.get("/static/app.js").headers["content-type"]
    js = client.get("/static/pen-input.js").text
    assert "getCoalescedEvents" in js
    assert "touch-action: none" in client.get("/static/style.css").text
    assert client.get("/static/nope.js").status_code == 404


def test_textures_listing_png_and_features(client):
    lst = client.get("/api/textures").json()
    assert len(lst) >= 6
    ids = [t["id"] for t in lst]
    assert "patchwork" in ids
    t = lst[0]
    assert t["width_mm"] > 30 and t["features"]["spatial_frequency_per_m"] > 0
    png = client.get(t["url"])
    assert png.status_code == 200 and png.headers["content-type"] == "image/png" and png.content[:8] == b"\x89PNG\r\n\x1a\n"
    f = client.get("/api/textures/patchwork/features").json()
    grid = np.array(f["map"]["spatial_frequency_per_m"])
    assert grid.max() > 3 * grid.min()
    assert client.get("/api/textures/velvet.png").status_code == 404
    assert "velvet" in client.get("/api/textures/velvet/features").json()["error"]


def test_profiles_config_and_extra_router(client):
    p = client.get("/api/profiles").json()
    names = [x["name"] for x in p["profiles"]]
    assert p["default"] == "paper" and "physical" in names
    c = client.get("/api/config").json()
    assert c["default_mm_per_px"] == pytest.approx(25.4 / 96)
    assert c["output"] == "fake" and c["channels"] == 2
    assert client.get("/api/extra-ping").json() == {"ok": True}


def test_upload_ok_and_usable(client):
    rng = np.random.default_rng(0)
    x = np.arange(200)
    grating = (127 + 100 * np.cos(2 * np.pi * x / 10)[None, :] + rng.normal(0, 2, (150, 200))).clip(0, 255).astype(np.uint8)
    data = png_bytes(grating, 96.0)
    r = client.post("/api/textures", files={"file": ("stripes.png", data, "image/png")}, data={"width_mm": "100"})
    assert r.status_code == 201, r.text
    body = r.json()
    assert body["width_mm"] == pytest.approx(100.0)
    # 20 periods across 100 mm: 200 cycles/m
    assert body["features"]["spatial_frequency_per_m"] == pytest.approx(200.0, rel=0.02)
    assert any(t["id"] == body["id"] for t in client.get("/api/textures").json())
    assert client.get(body["url"]).status_code == 200
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        ready = hello(ws, body["id"])
        assert ready["texture_width_mm"] == pytest.approx(100.0)


def test_upload_refusals(client):
    r = client.post("/api/textures", files={"file": ("notes.txt", b"hello, not an image", "text/plain")})
    assert r.status_code == 415 and "notes.txt" in r.json()["error"] and "not an image" in r.json()["error"]
    big = b"\x89PNG" + b"\0" * (12 * 1024 * 1024)
    r = client.post("/api/textures", files={"file": ("huge.png", big, "image/png")})
    assert r.status_code == 413 and "too large" in r.json()["error"]
    r = client.post("/api/textures", files={"file": ("empty.png", b"", "image/png")})
    assert r.status_code == 422 and "empty" in r.json()["error"]
    good = png_bytes(np.zeros((8, 8), np.uint8), 96)
    r = client.post("/api/textures", files={"file": ("a.png", good, "image/png")}, data={"width_mm": "-3"})
    assert r.status_code == 422 and "width_mm" in r.json()["error"]
    r = client.post("/api/textures", files={"file": ("a.png", good[:30], "image/png")})
    assert r.status_code in (415, 422) and "a.png" in r.json()["error"]
    r = client.post("/api/textures", data={"width_mm": "10"})
    assert r.status_code in (400, 422) and "file" in r.json()["error"]
    r = client.post("/api/textures", content=b"--x\r\ngarbage", headers={"content-type": "multipart/form-data; boundary=x"})
    assert r.status_code in (400, 422) and "error" in r.json()
    r = client.post("/api/textures", files={"file": ("a.png", good, "image/png")}, data={"width_mm": "10", "dpi": "300"})
    assert r.status_code == 422 and "not both" in r.json()["error"]
    # a decompression bomb: a header claiming 20000 x 20000 pixels
    from PIL import Image

    buf = io.BytesIO()
    Image.new("1", (20000, 20000)).save(buf, format="PNG")
    r = client.post("/api/textures", files={"file": ("bomb.png", buf.getvalue(), "image/png")})
    assert r.status_code == 422 and "too large" in r.json()["error"]


# ------------------------------------------------------------------- the pages' sample rows


def test_sample_rows_are_validated():
    assert sample_error([1.0, 2.0, 3.0]) is None
    assert sample_error([1.0, 2.0, 3.0, None, 0, 0]) is None
    assert "array" in sample_error({"t": 1})
    assert "3 to 6" in sample_error([1.0, 2.0])
    assert "finite" in sample_error([1.0, float("nan"), 3.0])
    assert "finite" in sample_error([1.0, "2", 3.0])
    assert "finite" in sample_error([True, 2.0, 3.0])
    assert "pressure" in sample_error([1.0, 2.0, 3.0, 1.5])


def test_css_conversion_uses_calibration():
    rows = [[1000.0, 100.0, 50.0, 0.3, 10.0, -20.0]]
    (s,) = samples_from_css(rows, 0.5e-3)
    assert (s.t_s, s.x_m, s.y_m, s.pressure, s.tilt_x_deg, s.tilt_y_deg) == (1.0, 0.05, 0.025, 0.3, 10.0, -20.0)


def test_short_rows_get_no_pressure_and_no_tilt():
    a, b = samples_from_css([[1000.0, 100.0, 50.0], [1001.0, 100.0, 50.0, 0.25]], 1e-3)
    assert (a.pressure, a.tilt_x_deg, a.tilt_y_deg) == (None, 0.0, 0.0)
    assert (b.pressure, b.tilt_x_deg, b.tilt_y_deg) == (0.25, 0.0, 0.0)


def test_integers_beyond_any_float_are_refused():
    assert "finite" in sample_error([10**400, 2.0, 3.0])


# ------------------------------------------------------------------- one JSON encoder


def test_encoder_writes_nan_as_null_in_both_forms():
    from tactilize.encode import dumps

    doc = {"a": float("nan"), "b": [float("inf"), 1.5], "c": np.float32(np.nan), "d": np.arange(2), "e": (1, 2)}
    for compact in (True, False):
        assert json.loads(dumps(doc, compact=compact)) == {"a": None, "b": [None, 1.5], "c": None, "d": [0, 1], "e": [1, 2]}
    assert "\n" not in dumps(doc, compact=True) and "\n" in dumps(doc)
    # What orjson refuses takes the json module's path, with the same rules.
    odd = {1: float("nan"), "big": 2**70}
    assert json.loads(dumps(odd, compact=True)) == {"1": None, "big": 2**70}


def test_cli_and_page_share_the_encoder():
    import tactilize.cli as cli
    import tactilize.experiments.cli as experiments_cli
    from tactilize import encode

    assert cli.dumps is encode.dumps is session_mod.dumps is experiments_cli.dumps


# ------------------------------------------------------------------- errors


def test_any_tactilize_error_a_route_raises_is_answered_not_a_500():
    from fastapi import FastAPI

    from tactilize.errors import ProfileError, RequestError
    from tactilize.http import ErrorAnsweringRoute

    router = APIRouter(route_class=ErrorAnsweringRoute)

    @router.get("/refused")
    def refused():
        raise RequestError("thing", "not today", 409, hint="tomorrow")

    @router.get("/bad")
    async def bad():
        raise ProfileError("velvet", "unknown profile")

    app = FastAPI()
    app.include_router(router)  # a bare app: the routes answer errors themselves
    with TestClient(app, base_url="http://127.0.0.1") as c:
        r = c.get("/refused")
        assert r.status_code == 409 and r.json() == {"error": "not today", "source": "thing", "hint": "tomorrow"}
        r = c.get("/bad")
        assert r.status_code == 422 and r.json() == {"error": "velvet: unknown profile", "source": "velvet"}


# ------------------------------------------------------------------- websocket


def test_ws_stroke_speeds_and_lift(client, output):
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        ready = hello(ws)
        assert ready["profile"] == "paper" and ready["limits"]["max_frequency_hz"] == 300.0
        freqs, speeds = [], []
        for i, v in enumerate((10.0, 40.0)):
            ws.send_text(json.dumps({"type": "samples", "batch": str(2 * i), "samples": stroke_rows(v)}))
            d = recv_type(ws, "drive")
            assert d["batch"] == str(2 * i) and d["on"] and d["inside"]
            freqs.append(d["channels"][0]["pulse_frequency_hz"])
            speeds.append(d["speed_mm_s"])
            stops = output.stops
            ws.send_text(json.dumps({"type": "lift", "batch": str(2 * i + 1)}))
            off = recv_type(ws, "drive")
            assert not off["on"] and not off["down"] and off["channels"][0]["pulse_frequency_hz"] == 0
            assert output.stops == stops + 1
        assert speeds[0] == pytest.approx(10.0, rel=1e-3) and speeds[1] == pytest.approx(40.0, rel=1e-3)
        assert freqs[1] > 2 * freqs[0]
        assert len(output.applied[-1]) == 2


def test_ws_calibration_is_the_pages_and_restarts_the_stroke(client):
    """Positions arrive in mm: the page converts with its calibration; the server only
    records the scale and starts a new stroke."""
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws)
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0)}))
        a = recv_type(ws, "drive")["speed_mm_s"]
        ws.send_text(json.dumps({"type": "calibrate", "mm_per_px": 2 * 25.4 / 96}))
        st = recv_type(ws, "state")
        assert st["mm_per_px"] == pytest.approx(2 * 25.4 / 96)
        # The page measures the same hand movement in px; at twice the mm per px it sends twice the mm.
        rows = stroke_rows(20.0, t0=1100.0, mm_per_px=25.4 / 96)
        ws.send_text(json.dumps({"type": "samples", "samples": [[r[0], 2 * r[1], 2 * r[2], *r[3:]] for r in rows]}))
        b = recv_type(ws, "drive")["speed_mm_s"]
        assert a == pytest.approx(20.0, rel=1e-3) and b == pytest.approx(2 * a, rel=1e-6)


def test_ws_profile_switch(client):
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws)
        ws.send_text(json.dumps({"type": "profile", "name": "physical"}))
        assert recv_type(ws, "state")["profile"] == "physical"
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0)}))
        d = recv_type(ws, "drive")
        # physical: f = v * f_s (vertical ribs, horizontal stroke: cos = 1)
        assert d["channels"][0]["pulse_frequency_hz"] == pytest.approx(0.020 * d["spatial_frequency_per_m"], rel=1e-3)
        ws.send_text(json.dumps({"type": "profile", "name": "../../etc/passwd"}))
        assert "unknown profile" in recv_type(ws, "error")["message"]


def test_ws_leaving_picture_stops(client, output):
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws)
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0)}))
        assert recv_type(ws, "drive")["on"]
        stops = output.stops
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0, x0=-50.0, t0=1100.0)}))
        d = recv_type(ws, "drive")
        assert not d["on"] and not d["inside"] and d["down"]
        assert output.stops == stops + 1


BAD_MESSAGES = [
    ("not json at all", "not JSON"),
    ("[1, 2, 3]", "JSON object"),
    ('{"no": "type"}', "unknown message type"),
    ('{"type": "dance"}', "unknown message type"),
    ('{"type": "samples"}', "'samples' must be an array"),
    ('{"type": "samples", "samples": [[1, 2]]}', "sample 0"),
    ('{"type": "samples", "samples": [[1, "x", 3]]}', "finite number"),
    ('{"type": "samples", "samples": [[1, 2, 3, 7]]}', "pressure"),
    ('{"type": "samples", "samples": [[1e400, 2, 3]]}', "finite"),
    ('{"type": "samples", "samples": [{"t": 1}]}', "array"),
    ('{"type": "texture"}', "needs an 'id'"),
    ('{"type": "texture", "id": "velvet"}', "no texture"),
    ('{"type": "texture", "id": 7}', "must be a string"),
    ('{"type": "calibrate", "mm_per_px": 0}', "mm_per_px"),
    ('{"type": "calibrate", "mm_per_px": "big"}', "mm_per_px"),
    ('{"type": "calibrate"}', "needs 'mm_per_px'"),
    ('{"type": "profile", "name": 3}', "must be a string"),
    ("[" * 5000 + "]" * 5000, "JSON"),
]


def test_ws_malformed_messages_get_errors_and_connection_lives(client):
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws)
        for text, expect in BAD_MESSAGES:
            ws.send_text(text)
            m = ws.receive_json()
            assert m["type"] == "error" and expect in m["message"], (text[:40], m)
        ws.send_bytes(b"\x00\x01binary")
        assert "binary" in ws.receive_json()["message"]
        ws.send_text(json.dumps({"type": "samples", "samples": [[0, 0, 0]] * (session_mod.MAX_BATCH + 1)}))
        assert "too many samples" in ws.receive_json()["message"]
        ws.send_text("x" * (session_mod.MAX_MESSAGE_CHARS + 1))
        assert "too long" in ws.receive_json()["message"]
        # still alive and working
        ws.send_text(json.dumps({"type": "ping", "id": 42}))
        assert ws.receive_json() == {"type": "pong", "id": 42, "server_time_s": pytest.approx(time.time(), abs=60)}
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0)}))
        assert recv_type(ws, "drive")["on"]


#: Batches whose finite values are near the float limit: their differences overflow.
HUGE = 1.7e308
HUGE_BATCHES = [
    [[0, 10, 10, 0.5], [8, HUGE, 10, 0.5], [16, 12, 10, 0.5]],
    [[0, 10, 10, 0.5], [8, -HUGE, HUGE, 0.5]],
    [[0, 10, -HUGE, 0.5], [8, 10, 10, 0.5]],
    [[HUGE, 10, 10, 0.5], [-HUGE, 12, 10, 0.5]],
    [[0, 10, 10, 0.5, HUGE, 0.0]],
]


@pytest.mark.parametrize("profile", ["surface", "paper"])
def test_ws_batches_near_the_float_limit_are_refused_and_the_session_lives(client, profile):
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws, profile=profile)
        for k, rows in enumerate(HUGE_BATCHES):
            ws.send_text(json.dumps({"type": "samples", "batch": str(k), "samples": rows}))
            m = recv_type(ws, "error")
            assert "must be within" in m["message"], m
        # The session is the same one, still stroking.
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0, t0=5000.0)}))
        assert recv_type(ws, "drive")["on"]


def test_ws_samples_before_texture_are_refused(client):
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0)}))
        assert "no texture selected" in ws.receive_json()["message"]


def test_ws_flood_is_bounded_and_latest_wins(client):
    app = client.app
    state = app.state.tactilize
    dropped_before = state.counters.get("samples_dropped", 0)
    n_msgs, per = 400, 50
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws)
        t = 1000.0
        x = 10.0
        for k in range(n_msgs):
            rows = []
            for _ in range(per):
                t += 1.0
                x = 10.0 + (t - 1000.0) * 0.002  # 2 mm/s in mm/ms
                rows.append([t, x, 30.0, 0.5])
            ws.send_text(json.dumps({"type": "samples", "batch": str(k), "samples": rows}))
        ws.send_text(json.dumps({"type": "ping", "id": "end"}))
        drives = []
        while True:
            m = ws.receive_json()
            if m["type"] == "drive":
                drives.append(m)
            if m["type"] == "pong":
                break
        # The renderer may lag the pong by one batch; collect what is left.
        deadline = time.time() + 2
        while (not drives or drives[-1]["batch"] != str(n_msgs - 1)) and time.time() < deadline:
            m = ws.receive_json()
            if m["type"] == "drive":
                drives.append(m)
    assert drives and drives[-1]["batch"] == str(n_msgs - 1)  # the newest batch was rendered
    assert drives[-1]["x_m"] == pytest.approx(x * 1e-3)
    assert len(drives) <= n_msgs  # never more drives than batches
    # 20,000 samples went in; whatever was dropped on the way was counted, not queued.
    received = state.counters["samples_received"]
    assert received >= n_msgs * per
    assert state.counters.get("samples_dropped", 0) - dropped_before <= n_msgs * per


def test_pending_queue_bound_directly(client):
    s = session_mod.PenSession(client.app.state.tactilize)
    s.handle(json.dumps({"type": "texture", "id": "corduroy"}))
    for k in range(100):
        rows = [[k * 100.0 + i, 10.0 + i * 0.01, 30.0] for i in range(100)]
        s.handle(json.dumps({"type": "samples", "batch": str(k), "samples": rows}))
        assert len(s.pending) <= session_mod.MAX_PENDING
    newest = list(s.pending)[-1]  # newest kept, in SI
    assert (newest.t_s, newest.x_m, newest.y_m) == pytest.approx((9.999, (10.0 + 99 * 0.01) * 1e-3, 0.03))
    s.handle(json.dumps({"type": "lift"}))
    assert not s.pending and s.pending_lift
    msg = s.render_pending()
    assert msg["type"] == "drive" and not msg["on"]
    s.close()


def test_resting_pen_falls_to_zero_speed(client, monkeypatch):
    monkeypatch.setattr(session_mod, "IDLE_S", 0.03)
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws)
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(30.0)}))
        moving = recv_type(ws, "drive")
        rest = recv_type(ws, "drive")  # sent by the server on its own after IDLE_S
        assert moving["speed_mm_s"] > 20 and not moving["resting"]
        assert rest["resting"] and rest["speed_mm_s"] == 0.0 and rest["down"]
        assert rest["channels"][0]["pulse_frequency_hz"] < moving["channels"][0]["pulse_frequency_hz"]


def test_disconnect_stops_output(output):
    out = FakeOutput()
    app = create_app(out, Profile.preset("paper"), warm=False)
    with TestClient(app, base_url="http://127.0.0.1") as c:
        with c.websocket_connect("ws://127.0.0.1/ws") as ws:
            hello(ws)
            ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0)}))
            recv_type(ws, "drive")
            assert out.stops == 0
        deadline = time.monotonic() + 30  # a bound only
        while out.stops == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert out.stops >= 1
        stats = c.get("/api/stats").json()
        assert stats["batches"] >= 1 and stats["server_latency_us"]["p50"] > 0
    assert not out.closed  # the app did not open it, so it does not close it


# ------------------------------------------------------------------- output faults


def test_output_errors_reach_the_page():
    from starlette.websockets import WebSocketDisconnect

    from tactilize.errors import OutputError

    class Flaky(FakeOutput):
        def __init__(self, exc):
            super().__init__()
            self.exc = exc

        def apply(self, channels):
            raise self.exc

    # A device fault the output reports: the page is told, the connection lives.
    out = Flaky(OutputError("serial:/dev/ttyACM0", "controller not answering"))
    with TestClient(create_app(out, "paper", warm=False), base_url="http://127.0.0.1") as c:
        with c.websocket_connect("ws://127.0.0.1/ws") as ws:
            hello(ws)
            ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0)}))
            assert "controller not answering" in recv_type(ws, "error")["message"]
            ws.send_text(json.dumps({"type": "ping", "id": 1}))
            assert recv_type(ws, "pong")["id"] == 1
    # A bug: the connection is closed (1011) and the output stopped, no hang.
    out = Flaky(RuntimeError("boom"))
    with TestClient(create_app(out, "paper", warm=False), base_url="http://127.0.0.1") as c:
        with c.websocket_connect("ws://127.0.0.1/ws") as ws:
            hello(ws)
            ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0)}))
            with pytest.raises(WebSocketDisconnect) as info:
                for _ in range(20):
                    ws.send_text(json.dumps({"type": "ping", "id": 2}))
                    ws.receive_json()
            assert info.value.code == 1011
    assert out.stops >= 1  # whatever apply half-did was stopped


def test_ws_hover_and_lift_hold_the_simulated_wire_in_standby():
    from tactilize.actuators.simulated import SimulatedOutput

    out = SimulatedOutput(start=False)
    app = create_app(out, "paper", output_name="simulated")
    with TestClient(app, base_url="http://127.0.0.1") as c, c.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws)
        states = lambda: [ctrl.state for ctrl in out.controllers]  # noqa: E731
        assert states() == ["off", "off"]
        ws.send_text(json.dumps({"type": "hover"}))
        ws.send_text(json.dumps({"type": "ping", "id": 1}))
        recv_type(ws, "pong")
        out.advance(0.1)
        assert states() == ["standby", "standby"]
        ws.send_text(json.dumps({"type": "samples", "batch": "1", "samples": stroke_rows(40.0)}))
        d = recv_type(ws, "drive")
        assert d["on"]
        out.advance(0.05)
        assert states() == ["vibrating", "vibrating"]
        ws.send_text(json.dumps({"type": "lift", "batch": "2"}))
        assert not recv_type(ws, "drive")["on"]
        out.advance(0.05)
        # lifted: texture off, wire still ready (not cold and off)
        assert states() == ["standby", "standby"]
        assert all(ctrl.bias_level > 0 for ctrl in out.controllers)


def test_the_warm_heap_is_frozen_out_of_the_collectors_sight(output):
    # After the warm-up, what exists lives as long as the server: a full collection
    # must not walk it again (it stopped the event loop for 80 .. 130 ms).
    import gc

    gc.unfreeze()
    assert gc.get_freeze_count() == 0
    try:
        with TestClient(create_app(output, "paper", output_name="fake"), base_url="http://127.0.0.1"):
            t0 = time.monotonic()
            while gc.get_freeze_count() == 0 and time.monotonic() - t0 < 60:
                time.sleep(0.05)
            frozen = gc.get_freeze_count()
        assert frozen > 10_000  # the libraries and the built-in maps, at least
        # Without the warm-up nothing is frozen (an embedding application decides).
        gc.unfreeze()
        with TestClient(create_app(output, "paper", output_name="fake", warm=False), base_url="http://127.0.0.1"):
            time.sleep(0.2)
            assert gc.get_freeze_count() == 0
    finally:
        gc.unfreeze()
