"""One output, many pages: a physical output is held by one page at a time, a simulated one
is each page's own (docs/safety.md, "Who may touch what")."""

from __future__ import annotations

import json

import pytest
from fastapi.testclient import TestClient

from tactilize.actuators.recording import RecordingOutput
from tactilize.drive import Drive
from tactilize.surface.rendering import Frame
from tactilize.web import create_app
from tactilize.web.ownership import PEN, TRIAL, LeasedOutput, OutputLease

LOCAL = "http://127.0.0.1"
WS = "ws://127.0.0.1/ws"


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def rows(v_mm_s=20.0, t0=1000.0, n=20, dt_ms=5.0):
    v_mm_ms = v_mm_s / 1e3
    return [[t0 + i * dt_ms, 5.0 + v_mm_ms * i * dt_ms, 8.0, 0.5] for i in range(n)]


def recv(ws, kind, limit=50):
    for _ in range(limit):
        m = ws.receive_json()
        if m["type"] == kind:
            return m
    raise AssertionError(f"no {kind} message")


def standing(ws, state, limit=50):
    """The next output message saying ``state`` (earlier standings are skipped)."""
    for _ in range(limit):
        m = recv(ws, "output")
        if m["state"] == state:
            return m
    raise AssertionError(f"never told {state}")


def stroke(ws, seq, t0=1000.0, v_mm_s=20.0):
    ws.send_text(json.dumps({"type": "samples", "batch": str(seq), "samples": rows(v_mm_s, t0=t0)}))
    for _ in range(50):  # resting drives of the earlier batch may come first
        d = recv(ws, "drive")
        if d["batch"] == str(seq) and not d["resting"]:
            return d
    raise AssertionError(f"no drive for batch {seq}")


def test_the_lease_first_stroke_holds_silence_frees_and_a_trial_outranks_the_pen():
    clock = Clock()
    lease = OutputLease(idle_s=10.0, clock=clock)
    told = {"a": [], "b": [], "t": []}
    out = RecordingOutput()
    a = LeasedOutput(out, lease, PEN, told["a"].append)
    b = LeasedOutput(out, lease, PEN, told["b"].append)
    off = RecordingOutput().apply([])
    on = [d.replace(pulse_frequency_hz=20.0, pulse_width_s=0.004) for d in off]
    a.apply(on)
    assert lease.holds(a) and len(out.applied) == 1
    b.apply(on)  # refused: nothing reaches the device, b is told, once
    b.apply(on)
    b.stop()
    b.standby()
    assert len(out.applied) == 1 and out.stops == 0 and b.refused == 2
    assert [m["state"] for m in told["b"]] == ["in_use"] and told["b"][0]["take_over"] is True
    clock.t += 9.9
    b.apply(on)
    assert len(out.applied) == 1
    clock.t += 0.1  # a silent holder no longer keeps others out
    b.apply(on)
    assert lease.holds(b) and len(out.applied) == 2 and told["a"][-1]["state"] == "in_use"
    # A trial outranks the pen page at once, and the pen page cannot take it back.
    t = LeasedOutput(out, lease, TRIAL, told["t"].append)
    t.apply(on)
    assert lease.holds(t) and told["b"][-1] == {"type": "output", "state": "in_use", "by": "experiment trial",
                                                "take_over": False}
    assert b.take_over()["state"] == "in_use" and lease.holds(t)
    t.close()  # the trial page goes: the device rests, every page hears it is free
    assert out.stops == 1 and told["a"][-1]["state"] == "free" and told["b"][-1]["state"] == "free"
    assert a.take_over()["state"] == "yours" and told["b"][-1]["state"] == "in_use"


@pytest.fixture()
def shared():
    out = RecordingOutput()
    app = create_app(out, "paper", warm=False)
    with TestClient(app, base_url=LOCAL) as c:
        yield c, out, app.state.tactilize


def hello(ws):
    ws.send_text(json.dumps({"type": "hello", "texture": "corduroy"}))
    return recv(ws, "ready")


def freq(drive_msg):
    return drive_msg["channels"][0]["requested_frequency_hz"]


def played(out, f_hz):
    """Was a drive of this frequency ever played on the device?"""
    return any(abs(d[0].pulse_frequency_hz - f_hz) < 1e-9 for d in out.applied)


def test_a_second_page_neither_rests_nor_replaces_the_first_pages_drive(shared):
    c, out, _ = shared
    with c.websocket_connect(WS) as first:
        hello(first)
        d1 = stroke(first, 1)
        assert d1["on"] and played(out, freq(d1))
        # A second page connects, hovers and closes: the first page's wire is not sent to standby.
        with c.websocket_connect(WS) as second:
            hello(second)
            second.send_text(json.dumps({"type": "hover"}))
            second.send_text(json.dumps({"type": "ping", "id": 1}))
            recv(second, "pong")
        assert out.stops == 0
        # A second page that strokes is told the output is in use; its drive never reaches it.
        with c.websocket_connect(WS) as second:
            hello(second)
            second.send_text(json.dumps({"type": "samples", "batch": "1", "samples": rows(v_mm_s=80.0)}))
            status = recv(second, "output")
            assert status["state"] == "in_use" and status["take_over"] is True
            d2 = recv(second, "drive")
            assert not d2["on"] and abs(freq(d2) - freq(d1)) > 1.0 and not played(out, freq(d2))
            second.send_text(json.dumps({"type": "lift", "batch": "2"}))
            recv(second, "drive")
            assert out.stops == 0
            # ...and may take it over: the first page is told.
            second.send_text(json.dumps({"type": "take_over"}))
            assert recv(second, "output")["state"] == "yours"
            assert standing(first, "in_use")["take_over"] is True
            d3 = stroke(second, 3, t0=2000.0)
            assert d3["on"] and played(out, freq(d3))
        standing(first, "free")
        assert stroke(first, 2, t0=3000.0)["on"]


def test_a_trial_holds_the_device_before_the_pen_page(tmp_path):
    from tactilize.experiments.flow import Flow
    from tactilize.experiments.protocols import load_protocol
    from tactilize.experiments.store import Store
    from tactilize.experiments.web import experiment_router

    flow = Flow(load_protocol("alpha-law"), Store(str(tmp_path / "x.db")))
    out = RecordingOutput()
    app = create_app(out, "paper", warm=False, extra_routers=[experiment_router(flow)])
    token = flow.start("P1", True)["session"]
    state = flow.calibrate(token, {"mm_per_px": 0.25, "felt": True})
    trial, image = state["trial"]["index"], state["trial"]["images"][0]["id"]
    with TestClient(app, base_url=LOCAL) as c, c.websocket_connect(WS) as pen:
        hello(pen)
        assert played(out, freq(stroke(pen, 1)))
        with c.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as part:
            samples = [[1000 + 10 * i, 10 + 0.5 * i, 10, 0.5] for i in range(10)]
            part.send_text(json.dumps({"type": "samples", "trial": trial, "image": image, "samples": samples}))
            reply = part.receive_json()
            assert reply["type"] == "drive" and played(out, reply["drive"]["pulse_frequency_hz"])
            assert standing(pen, "in_use") == {"type": "output", "state": "in_use", "by": "experiment trial",
                                               "take_over": False}
            n = len(out.applied)
            d = stroke(pen, 2, t0=2000.0, v_mm_s=60.0)  # another drive than the last (not a resend)
            assert not d["on"] and len(out.applied) == n
            pen.send_text(json.dumps({"type": "take_over"}))
            assert recv(pen, "output")["state"] == "in_use"
            assert len(out.applied) == n


def test_simulated_outputs_are_each_pages_own():
    made = []

    def factory():
        made.append(RecordingOutput())
        return made[-1]

    shared_out = RecordingOutput()
    app = create_app(shared_out, "paper", warm=False, page_outputs=factory)
    with TestClient(app, base_url=LOCAL) as c, c.websocket_connect(WS) as one:
        hello(one)
        stroke(one, 1)
        with c.websocket_connect(WS) as two:
            hello(two)
            ws_drive = stroke(two, 1)
            assert ws_drive["on"]
        # Each page's drives went to its own output (the first one's may add its resting drive).
        assert len(made) == 2 and len(made[0].applied) >= 1 and len(made[1].applied) >= 1
        assert made[0].stops == 0 and shared_out.applied == []
        before = len(made[1].applied)
        # A page that went leaves its wire to the next page (a reload finds it as it was).
        with c.websocket_connect(WS) as three:
            hello(three)
            stroke(three, 1)
        assert len(made) == 2 and len(made[1].applied) > before and made[0].stops == 0
    # The app's own simulated wire is per page too (tactilize serve passes the same).
    assert create_app(None, "paper", warm=False).state.tactilize.page_output_factory is not None


_NO_EVENTS = Frame((), Drive.off(), False)  # a frame of no events


class _EventsOutput:
    """Plays pulse events; records each hand-over and each after_batch()."""

    channels = 2

    def __init__(self) -> None:
        self.handed: list[float] = []
        self.quiet = 0

    def play(self, frame, now_s, channels):
        self.handed.append(now_s)
        return list(channels)

    def after_batch(self) -> None:
        self.quiet += 1


def test_a_stroke_of_events_claims_the_lease_like_a_steady_drive():
    clock = Clock()
    lease = OutputLease(idle_s=10.0, clock=clock)
    out = _EventsOutput()
    told_b: list = []
    a = LeasedOutput(out, lease, PEN)
    b = LeasedOutput(out, lease, PEN, told_b.append)
    on = [d.replace(pulse_frequency_hz=20.0, pulse_width_s=0.004) for d in RecordingOutput().apply([])]
    assert a.play(_NO_EVENTS, 1.0, on) == on
    assert lease.holds(a) and out.handed == [1.0]
    # The holder's batches let the output's background work run in the gap after them.
    a.after_batch()
    assert out.quiet == 1
    # Another page's events do not replace the holder's: refused, told once, not played.
    refused = b.play(_NO_EVENTS, 2.0, on)
    b.play(_NO_EVENTS, 2.1, on)
    b.after_batch()
    assert out.handed == [1.0] and out.quiet == 1 and b.refused == 2
    assert all(d.is_off for d in refused) and len(refused) == 2
    assert [m["state"] for m in told_b] == ["in_use"]
