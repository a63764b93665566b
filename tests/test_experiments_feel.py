"""A participant feels what ``tactilize serve`` renders.

The same recorded stroke goes through the pen page's WebSocket and through an
experiment trial's WebSocket with the same profile, each app with its own
recording output; both must apply the same drives (or play the same pulse
events) batch for batch, with one injected clock and the same resend settings.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import pytest
from fastapi.testclient import TestClient

import tactilize.web.session as session_mod
from tactilize.actuators.base import OutputBase
from tactilize.drive import Drive
from tactilize.experiments.feel import WholePicture
from tactilize.experiments.flow import Flow
from tactilize.experiments.protocols import load_protocol
from tactilize.experiments.store import Store
from tactilize.experiments.web import experiment_router
from tactilize.pen import PenRenderer
from tactilize.pen.display import MM_PER_PX_RANGE
from tactilize.web import create_app
from tactilize.web.app import TextureEntry

LOCAL = "http://127.0.0.1"
MM_PER_PX = 0.5  # exact in binary: px * 0.5e-3 and (px * 0.5) * 1e-3 are the same float

SURFACE_PROTOCOL = """
name = "surface-check"
version = "1"
title = "Surface rendering"
description = "Stroke the picture."
base_profile = "surface"
repetitions = 1
trial_unit = "condition"
min_stroke_s = 0.0
require_every_image = false

[[images]]
id = "grating"
label = "Grating"
texture = "grating"
spatial_frequency_per_m = 400.0
spectral_intensity = 0.9

[[conditions]]
id = "A"
label = "the surface preset"

[[questions]]
id = "match"
text = "How well did the touch match the picture?"
anchors = { 1 = "not at all", 7 = "perfectly" }
"""


class Clock:
    """The injected clock: moves only when the test says so."""

    def __init__(self) -> None:
        self.t = 50.0

    def __call__(self) -> float:
        return self.t


@dataclass
class Recording(OutputBase):
    """Records everything the renderer asks of it, in order."""

    channels: int = 2
    log: list[tuple[Any, ...]] = field(default_factory=list)

    def apply(self, channels):
        self.log.append(("apply", tuple(d.to_dict()["pulse_frequency_hz"] for d in channels),
                         tuple(d.pulse_width_s for d in channels), tuple(d.amplitude for d in channels)))
        return list(channels)

    def play(self, frame, now_s, channels):
        return self.apply(channels)

    def standby(self):
        self.log.append(("standby",))

    def stop(self):
        self.log.append(("stop",))


class SMARecording(Recording):
    amplitude_is_intensity = False  # both pins play the texture's drive, as on the wire


class EventRecording(Recording):
    """Schedules events (a steady rendering's regular train it plays as its drive)."""

    def play(self, frame, now_s, channels):
        if frame.regular:
            return self.apply(channels)
        self.log.append(("events", now_s, tuple(tuple((e.t_s, e.strength) for e in frame.events)
                                                 for _ in channels)))
        return list(channels)


def _stroke_px(t0_ms: float, n_batches: int, per_batch: int = 4):
    """A stroke that speeds up and turns, in CSS px of the pen page, batch by batch."""
    batches = []
    for b in range(n_batches):
        rows = []
        for i in range(per_batch):
            k = b * per_batch + i
            a = 0.04 * k
            rows.append([t0_ms + 8.0 * k, 20.0 + 0.03 * k * k * math.cos(a), 30.0 + 0.03 * k * k * math.sin(a),
                         min(1.0, 0.2 + 0.01 * k)])
        batches.append(rows)
    return batches


def _straight_px(t0_ms: float, n_batches: int, per_batch: int = 4):
    """A straight stroke at a steady 60 mm/s: the same drive batch after batch."""
    step_px = 60.0 * 8e-3 / MM_PER_PX  # px per 8 ms sample
    return [[[t0_ms + 8.0 * k, 15.0 + step_px * k, 40.0, 0.5] for k in range(b * per_batch, (b + 1) * per_batch)]
            for b in range(n_batches)]


def _recording():
    """Two strokes with a lift between: ("samples", rows in px) and ("lift",) steps."""
    return ([("samples", rows) for rows in _stroke_px(1000.0, 14)] + [("lift",)]
            + [("samples", rows) for rows in _straight_px(1600.0, 16)] + [("lift",)])


def _mm(rows):
    """Rows in CSS px as both pages send them: millimetres on the picture, by the page's calibration."""
    return [[t, x * MM_PER_PX, y * MM_PER_PX, p] for t, x, y, p in rows]


def _next(ws, accept):
    for _ in range(100):
        m = ws.receive_json()
        if accept(m):
            return m
    raise AssertionError("no answer")


def _through_serve(profile, picture, surface, out, clock, monkeypatch):
    monkeypatch.setattr(session_mod, "PenRenderer", partial(PenRenderer, clock=clock))
    monkeypatch.setattr(session_mod, "IDLE_S", 1e6)  # no resting frame between the test's batches
    app = create_app(out, profile, warm=False)
    entry = TextureEntry("trial-picture", "trial picture", "", 0.04, 0.06, 600, 400, False,
                         lambda: b"", lambda: picture, lambda: surface)
    app.state.tactilize.textures[entry.id] = entry
    drives = []
    with TestClient(app, base_url=LOCAL) as c, c.websocket_connect("ws://127.0.0.1/ws") as ws:
        ws.send_text(json.dumps({"type": "hello", "texture": entry.id, "mm_per_px": MM_PER_PX}))
        _next(ws, lambda m: m["type"] == "ready")
        for seq, step in enumerate(_recording()):
            clock.t += 0.016
            before = len(out.log)
            if step[0] == "lift":
                ws.send_text(json.dumps({"type": "lift", "batch": str(seq)}))
            else:  # the same message the trial's page sends (millimetres), but its trial and image
                ws.send_text(json.dumps({"type": "samples", "batch": str(seq), "samples": _mm(step[1])}))
            _next(ws, lambda m: m["type"] == "drive" and m["batch"] == str(seq))
            drives.append(out.log[before:])
    return drives


def _through_trial(flow, token, trial, image, out, clock, monkeypatch):
    original = Flow.stroke_handler

    def with_clock(self, token, output=None):
        handler = original(self, token, output)
        handler.clock = clock
        return handler

    monkeypatch.setattr(Flow, "stroke_handler", with_clock)
    app = create_app(out, "paper", warm=False, extra_routers=[experiment_router(flow)])
    drives = []
    with TestClient(app, base_url=LOCAL) as c, c.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
        for k, step in enumerate(_recording()):
            clock.t += 0.016
            before = len(out.log)
            if step[0] == "lift":
                ws.send_text(json.dumps({"type": "lift"}))
                _next(ws, lambda m: m["type"] == "lifted")
            else:
                ws.send_text(json.dumps({"type": "samples", "trial": trial, "image": image, "batch": f"b{k}",
                                         "samples": _mm(step[1])}))
                _next(ws, lambda m: m["type"] == "drive" and m["batch"] == f"b{k}")
            drives.append(out.log[before:])
    return drives


def _same_felt(flow, output_cls, monkeypatch):
    token = flow.start("F1", True)["session"]
    state = flow.calibrate(token, {"mm_per_px": MM_PER_PX, "felt": True})
    trial, image = state["trial"]["index"], state["trial"]["images"][0]["id"]
    condition = flow.store.trials(flow.store.session_by_token(token).id)[trial].condition_id
    profile = flow.profile(condition)  # the trial's condition's, not the page's default
    surface = flow.image_surface(image) if profile.rendering == "surface" else None
    serve_out, trial_out = output_cls(), output_cls()
    served = _through_serve(profile, WholePicture(flow.image_features(image)), surface, serve_out, Clock(),
                            monkeypatch)
    felt = _through_trial(flow, token, trial, image, trial_out, Clock(), monkeypatch)
    return served, felt


@pytest.mark.parametrize("output_cls", [Recording, SMARecording], ids=["phantom-split", "sma-both-pins"])
def test_a_trial_applies_the_drives_serve_applies_batch_for_batch(tmp_path, monkeypatch, output_cls):
    flow = Flow(load_protocol("g-law"), Store(f"sqlite:///{tmp_path / 'feel.sqlite3'}"))
    served, felt = _same_felt(flow, output_cls, monkeypatch)
    assert felt == served  # equal floats, batch for batch
    applies = [e for batch in served for e in batch if e[0] == "apply"]
    # The resend rule acted (some batches sent nothing) and the refresh did too (not all skipped).
    assert 5 < len(applies) < len(served) - 2
    # A lift rests the wire in standby (the next touch starts warm), never stops it.
    assert ("standby",) in served[14] and ("stop",) not in [e for b in felt for e in b]
    if output_cls is Recording:  # an intensity output: the phantom sensation splits the stroke over two
        assert any(a[3][0] != a[3][1] for a in applies)
    else:
        assert all(a[1][0] == a[1][1] and a[3][0] == a[3][1] for a in applies)


def test_a_surface_trial_plays_the_pulse_events_serve_plays(tmp_path, monkeypatch):
    path = tmp_path / "surface-check.toml"
    path.write_text(SURFACE_PROTOCOL)
    flow = Flow(load_protocol(str(path)), Store(f"sqlite:///{tmp_path / 'feel.sqlite3'}"))
    assert flow.profile("A").rendering == "surface"
    served, felt = _same_felt(flow, EventRecording, monkeypatch)
    assert felt == served
    events = [e for batch in served for e in batch if e[0] == "events"]
    assert sum(len(e[2][0]) for e in events) > 5  # bumps were crossed and fired


def test_one_display_scale_rule_for_the_page_and_the_calibration(tmp_path):
    flow = Flow(load_protocol("alpha-law"), Store(f"sqlite:///{tmp_path / 'scale.sqlite3'}"))
    assert session_mod.MM_PER_PX_RANGE is MM_PER_PX_RANGE
    lo, hi = MM_PER_PX_RANGE
    for k, mm in enumerate((lo, 0.02, 2.0, hi)):  # the page takes them; so does the calibration check
        token = flow.start(f"S{k}", True)["session"]
        assert flow.calibrate(token, {"mm_per_px": mm, "felt": True})["calibration"]["mm_per_px"] == mm
    token = flow.start("S9", True)["session"]
    for mm in (lo * 0.99, hi * 1.01, float("nan"), True):
        with pytest.raises(Exception, match="screen scale"):
            flow.calibrate(token, {"mm_per_px": mm, "felt": True})
    assert Drive.off().is_off
