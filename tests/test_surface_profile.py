"""The surface rendering as the default: profiles name their rendering, the paper preset is untouched,
the commands and the page use it, and the pen renderer drives outputs with events or their equivalent."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from tactilize.actuators.simulated import SimulatedOutput
from tactilize.drive import Drive
from tactilize.errors import ProfileError
from tactilize.mapping import DriveFeatures, Profile
from tactilize.actuators.recording import RecordingOutput
from tactilize.pen import PenRenderer, PenSample
from tactilize.surface import surface_model
from tactilize.surface.equivalent import equivalent_drive, regularity_of_cv
from tactilize.surface.events import PulseEvent
from tactilize.surface.fields import grain_field
from tactilize.maps.texturemap import texture_map
from tactilize.image import TextureImage


def test_paper_preset_frequencies_and_widths_unchanged():
    paper = Profile.preset("paper")
    assert paper.rendering == "steady"
    for f_s, i_s in ((200.0, 0.3), (1000.0, 0.5), (5000.0, 0.9)):
        for v_mm in (10.0, 60.0, 160.0):
            d = paper.drive(DriveFeatures(f_s, i_s), v_mm / 1e3)
            alpha = 2.9 / (1 + math.exp(-0.05 * (v_mm - 60.0))) + 0.1
            f = min(300.0, max(1.0, alpha * 40.0 * math.log(f_s + 1)))
            w = 0.4e-3 * i_s
            w = min(w, 0.1 / f)
            assert d.pulse_frequency_hz == pytest.approx(f, rel=1e-12)
            assert d.pulse_width_s == pytest.approx(w, rel=1e-12)


def test_a_profile_names_its_rendering_and_old_files_load(tmp_path):
    old = tmp_path / "old.toml"
    text = Profile.preset("physical").to_toml()
    assert "rendering" not in text
    old.write_text(text)
    assert Profile.load(old).rendering == "steady"
    surf = Profile.preset("surface")
    assert surf.rendering == "surface" and surf.tip_radius_m == pytest.approx(0.25e-3)
    back = tmp_path / "mine.toml"
    surf.replace(tip_radius_m=0.4e-3).save(back)
    again = Profile.load(back)
    assert again.rendering == "surface" and again.tip_radius_m == pytest.approx(0.4e-3)
    with pytest.raises(ProfileError):
        Profile.from_toml(text + '\nrendering = "sparkly"\n')
    with pytest.raises(ProfileError):
        Profile.from_toml('rendering = "surface"\n[surface]\ntip_radius_mm = -1\n' + text)


def test_equivalent_drive_carries_rate_cv_and_strength():
    even = [PulseEvent(0.01 * k, 0.5) for k in range(10)]
    d = equivalent_drive(even, now_s=0.09)
    assert d.pulse_frequency_hz == pytest.approx(100.0) and d.regularity == pytest.approx(1.0)
    assert d.strength == pytest.approx(0.5)
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.004, 0.016, 20))
    jittery = [PulseEvent(x, 0.2) for x in t]
    assert equivalent_drive(jittery, now_s=float(t[-1])).regularity < 0.5
    assert equivalent_drive([], now_s=1.0).is_off
    assert regularity_of_cv(0.0) == 1.0 and regularity_of_cv(1.0) == 0.0


def _picture(seed: int = 4):
    f = grain_field(2e-3, (60e-3, 20e-3), seed=seed)
    img = TextureImage(f.heights, (f.pitch_m, f.pitch_m))
    return img, texture_map(img), surface_model(img)


def _strokes(v=0.05, t_end=0.8, y=10e-3, rate=500.0):
    t = np.arange(0.0, t_end, 1 / rate)
    return [PenSample(a, 3e-3 + v * a, y, 0.5) for a in t]


def test_renderer_fires_events_on_the_simulated_wire():
    img, tmap, sm = _picture()
    out = SimulatedOutput(channels=2, start=False)
    # The host's clock moves with the simulated one: a loaded machine taking longer
    # between batches must not read as batches arriving late.
    host_s = [0.0]
    r = PenRenderer(tmap, Profile.preset("surface"), out, surface=sm, clock=lambda: host_s[0])
    out.standby()
    out.advance(1.0)
    samples = _strokes()
    scheduled = 0
    for k in range(0, len(samples), 2):
        res = r.feed(samples[k : k + 2])
        scheduled += len(res.events)
        assert res.to_dict()["events"] == len(res.events)
        out.advance(0.004)
        host_s[0] += 0.004
    fired = out.event_counts()[0]["fired"]
    assert fired >= 10 and scheduled >= fired
    # A resting pen is silent: nothing more fires.
    r.still()
    out.advance(0.5)
    assert out.event_counts()[0]["fired"] == fired


def test_renderer_gives_the_equivalent_drive_to_outputs_without_events():
    img, tmap, sm = _picture()
    rec = RecordingOutput()
    r = PenRenderer(tmap, Profile.preset("surface"), rec, surface=sm)
    samples = _strokes()
    for k in range(0, len(samples), 4):
        r.feed(samples[k : k + 4])
    # Audio-like outputs split the drive over the two channels by direction: take the louder.
    on = [max(d, key=lambda x: x.amplitude) for d in rec.applied if not all(x.is_off for x in d)]
    assert on, "the recorder got no drive"
    rates = [d.pulse_frequency_hz for d in on[len(on) // 2 :]]
    # grains of 2 mm at 50 mm/s: about 25 bumps a second
    assert 25 / 1.5 <= np.median(rates) <= 25 * 1.5
    # The same renderer on a steady profile ignores the surface: its frame's events are its
    # drive's own regular train (the outputs play that from the drive).
    from tactilize.surface.rendering import train_events

    r.set_profile(Profile.preset("paper"))
    r.lift()
    res = r.feed(samples[:40])
    assert res.regular and not all(d.is_off for d in res.applied)
    drive = r.rendering.frame(res.state, res.features, []).drive
    assert [e.t_s for e in res.events] == [e.t_s for e in train_events(drive, res.events[0].t_s, res.state.t_s)]


def test_commands_default_to_the_surface_rendering(tmp_path):
    from PIL import Image

    f = grain_field(2e-3, (50e-3, 22e-3), seed=3, px_per_pitch=10)  # the stroke runs along a row of grains
    path = tmp_path / "grains.png"
    Image.fromarray((f.heights * 255).astype("uint8")).save(path)
    env_cmd = [sys.executable, "-m", "tactilize.cli"]
    drive = json.loads(subprocess.run(env_cmd + ["drive", str(path), "--speed", "40", "--width-mm", "50", "--json"],
                                      capture_output=True, text=True, check=True).stdout)
    assert drive["profile"] == "surface" and drive["rendering"] == "surface"
    assert 20 / 1.5 <= drive["pulse_frequency_hz"] <= 20 * 1.5  # 40 mm/s over 2 mm grains
    paper = json.loads(subprocess.run(env_cmd + ["drive", str(path), "--speed", "40", "--width-mm", "50", "--json",
                                                 "--profile", "paper"], capture_output=True, text=True, check=True).stdout)
    assert paper["rendering"] == "steady" and paper["pulse_frequency_hz"] > 100
    rep = json.loads(subprocess.run(env_cmd + ["profile", "report", "--image", str(path), "--width-mm", "50",
                                               "--no-wire", "--json"], capture_output=True, text=True, check=True).stdout)
    assert rep["profile"] == "surface"
    rates = [r["frequency_hz"] for r in rep["rows"]]
    assert all(a < b for a, b in zip(rates, rates[1:]))  # faster stroke, more bumps a second
    assert all("interval_cv" in r and "pulses" in r for r in rep["rows"])
    from tactilize.web.serve import DEFAULT_PROFILE

    assert DEFAULT_PROFILE == "surface"


def test_page_session_sends_events_and_their_drive():
    from fastapi.testclient import TestClient

    from tactilize.web import create_app

    out = SimulatedOutput(start=False)
    with TestClient(create_app(out, "surface", output_name="simulated", warm=False, close_output=True), base_url="http://127.0.0.1") as client:
        with client.websocket_connect("ws://127.0.0.1/ws") as ws:
            ws.send_text(json.dumps({"type": "hello", "texture": "sandpaper"}))
            ready = next(m for m in iter(ws.receive_json, None) if m["type"] == "ready")
            assert ready["profile"] == "surface" and ready["rendering"] == "surface"
            v_mm_ms = 40.0 / 1e3
            events, on = 0, 0
            for k in range(150):  # 0.6 s in 4 ms batches
                t = 1000.0 + 4.0 * k
                rows = [[t, 5.0 + v_mm_ms * (t - 1000.0), 16.0, 0.5]]
                ws.send_text(json.dumps({"type": "samples", "batch": str(k), "samples": rows}))
                d = next(m for m in iter(ws.receive_json, None) if m["type"] == "drive")
                assert d["rendering"] == "surface"
                events += d["pulses"]
                on += d["on"]
    # sandpaper at 40 mm/s: about 40 bumps a second (profile report), so ~24 in 0.6 s
    assert 12 <= events <= 48
    assert on >= 100
