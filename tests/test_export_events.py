"""The parametric exports carry the surface's events, one per bump crossed where the format allows.

A generated bump field with known centres (tactilize.surface.fields) is stroked, synthetically and from a recorded
file; every AHAP, Android, .haptic and .hjif export is counted against the true crossings of the field: one
transient per bump where the bumps are far enough apart for the format's player, a continuous stretch following
the bumps' rate where they are not; every file passes its format's validator (the registry refuses any other).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from tactilize.drive import Drive
from tactilize.export import DriveTimeline, read_ahap, read_haptic, read_hjif, render, run_stroke, synthetic_stroke
from tactilize.export.conformance import check
from tactilize.export.events import (
    HJIF_TRANSIENT_S,
    INTENSITY_FLOOR,
    PHONE_TRANSIENT_S,
    BumpEvent,
    event_intensity,
    plan_events,
)
from tactilize.export.stroke import PREROLL_S, parse_stroke
from tactilize.image import load_image
from tactilize.mapping import Profile
from tactilize.surface import surface_model
from tactilize.surface.fields import bump_field
from tactilize.maps.texturemap import texture_map

PITCH_M = 1e-4  # 254 dpi
DPI = 0.0254 / PITCH_M
SIZE_M = (0.2, 0.02)
Y_M = SIZE_M[1] / 2
SPEED_M_S = 0.05
DURATION_S = 1.5
#: Sparse bumps 3 mm apart (60 ms at 50 mm/s), then dense ones 0.6 mm apart (12 ms, 83 /s).
SPARSE_X_M = 0.1065 + 0.003 * np.arange(12)
DENSE_X_M = 0.142 + 0.0006 * np.arange(47)
#: Crossing times of the synthetic stroke: it starts at the centre PREROLL_S before 0 s.
SPARSE_T = (SPARSE_X_M - SIZE_M[0] / 2) / SPEED_M_S - PREROLL_S
DENSE_T = (DENSE_X_M - SIZE_M[0] / 2) / SPEED_M_S - PREROLL_S
TOL_S = 0.002


def _field():
    """The bumps on the stroke's line, and as many 5 mm off it (never crossed: they must give nothing)."""
    xs = np.concatenate([SPARSE_X_M, DENSE_X_M])
    radii = np.concatenate([np.full(SPARSE_X_M.size, 1e-3), np.full(DENSE_X_M.size, 0.25e-3)])
    off = np.stack([xs + 0.0015, np.full(xs.size, Y_M + 0.005)], 1)
    centres = np.concatenate([np.stack([xs, np.full(xs.size, Y_M)], 1), off])
    return bump_field(centres, np.concatenate([radii, radii]), SIZE_M, PITCH_M)


@pytest.fixture(scope="module")
def field():
    f = _field()
    img = load_image(f.heights, dpi=DPI)
    profile = Profile.preset("surface")
    return img, texture_map(img), surface_model(img, tip_radius_m=profile.tip_radius_m), profile


@pytest.fixture(scope="module")
def synthetic(field):
    img, tmap, surface, profile = field
    stroke = synthetic_stroke(tmap.width_m, tmap.height_m, SPEED_M_S, DURATION_S)
    return run_stroke(stroke, tmap, profile, start_s=0.0, end_s=DURATION_S, mirror=True, surface=surface,
                      meta={"image": "bump field"})


def _docs(tl):
    # render() validates every document against its format's rules before it returns the bytes; so does this
    docs = {f: json.loads(render(tl, f)) for f in ("ahap", "android", "haptic", "hjif")}
    assert all(check(doc, f) == [] for f, doc in docs.items())
    return docs


def _match(found, true_t):
    """Every found time within TOL_S of its true crossing, one for one."""
    found = np.sort(np.asarray(found, dtype=float))
    assert found.size == len(true_t), (found.round(4).tolist(), np.round(true_t, 4).tolist())
    assert np.max(np.abs(found - np.sort(true_t))) <= TOL_S


def _match_x(found, ts, xs, centres):
    """Where the recorded path is at each found time: on its bump's centre within a pixel, one for one
    (in space: near the ends of a minimum-jerk stroke the pen is slow, and a pixel is milliseconds)."""
    found = np.sort(np.asarray(found, dtype=float))
    assert found.size == len(centres), (found.round(4).tolist(), len(centres))
    assert np.max(np.abs(np.interp(found, ts, xs) - np.sort(centres))) <= PITCH_M


def _primitives(doc):
    return [p for c in doc["compositions"] for p in c["primitives"]]


def test_the_events_are_the_true_crossings(synthetic):
    assert synthetic.events is not None
    t = np.array([e.t_s for e in synthetic.events])
    _match(t[t < 0.72], SPARSE_T)
    _match(t[t >= 0.72], DENSE_T)


def test_every_format_carries_one_transient_per_sparse_bump(synthetic):
    docs = _docs(synthetic)
    _match([tap.t_s for tap in read_ahap(docs["ahap"]).taps], SPARSE_T)
    _match([p["t_ms"] / 1e3 for p in _primitives(docs["android"])], SPARSE_T)
    _match([tap.t_s for tap in read_haptic(docs["haptic"]).taps], SPARSE_T)
    for c in range(2):  # both of the pen's actuators
        track = read_hjif(docs["hjif"], channel=c)
        _match([tap.t_s for tap in track.taps], SPARSE_T)
    # the delays rebuild the times: each from the previous primitive's start, none drifting
    for comp in docs["android"]["compositions"]:
        starts = np.cumsum([p["delay_ms"] for p in comp["primitives"]]) + comp["start_ms"]
        assert starts.tolist() == [p["t_ms"] for p in comp["primitives"]]


def test_dense_bumps_become_one_continuous_stretch_at_their_rate(synthetic):
    docs = _docs(synthetic)
    rate = SPEED_M_S / 0.0006  # 83 bumps a second
    cont = [e["Event"] for e in docs["ahap"]["Pattern"] if e.get("Event", {}).get("EventType") == "HapticContinuous"]
    assert len(cont) == 1
    assert abs(cont[0]["Time"] - DENSE_T[0]) <= TOL_S
    assert cont[0]["Time"] + cont[0]["EventDuration"] >= DENSE_T[-1]
    pts = [p for p in read_ahap(docs["ahap"]).points if DENSE_T[0] + 0.05 < p.t_s < DENSE_T[-1] - 0.05]
    assert pts and abs(np.median([p.frequency_hz for p in pts]) / rate - 1) < 0.15
    # Android: an envelope where the bumps are dense, at their rate, and no primitive there
    env = [e for e in docs["android"]["effects"] if e["kind"] == "waveform_envelope"]
    assert env and abs(env[0]["start_ms"] / 1e3 - DENSE_T[0]) <= TOL_S
    freqs = [c["frequency_hz"] for w in docs["android"]["waveform_envelopes"] for c in w["control_points"]]
    assert abs(np.median(freqs) / rate - 1) < 0.15
    assert all(e["kind"] == "composition" for e in docs["android"]["effects"] if e["start_ms"] < 720)
    # .haptic: amplitude over the dense stretch, no emphasis in it
    amp = docs["haptic"]["signals"]["continuous"]["envelopes"]["amplitude"]
    dense = [p for p in amp if DENSE_T[0] <= p["time"] <= DENSE_T[-1]]
    assert dense and all("emphasis" not in p for p in dense) and max(p["amplitude"] for p in dense) > 0.3
    # .hjif: one VectorialWave effect per channel there, keyframes at the rate
    for ch in docs["hjif"]["perceptions"][0]["channels"]:
        waves = [b for b in ch["bands"] if b["band_type"] == "VectorialWave"]
        assert len(waves) == 1 and abs(waves[0]["effects"][0]["position"] / 1e3 - DENSE_T[0]) <= TOL_S
        kf = [k["frequency_modulation"] for e in waves[0]["effects"] for k in e["keyframes"]]
        assert abs(np.median(kf) / rate - 1) < 0.15


def test_each_format_keeps_its_own_player_interval():
    """Bumps 21 ms apart: a phone plays them apart (20 ms), the MPEG synthesiser's 22 ms transient does not."""
    events = [BumpEvent(0.1 + 0.021 * k, 1.0, 30.0) for k in range(10)]
    tl = DriveTimeline.steady(Drive(50.0, 2e-4), 1.0)
    tl = DriveTimeline(tl.t_s, tl.end_s, tl.profile, tl.wire, tl.speed_m_s, tl.x_m, tl.y_m, {}, tuple(events))
    assert len(plan_events(events, PHONE_TRANSIENT_S).transients) == 10
    assert len(plan_events(events, HJIF_TRANSIENT_S).runs) == 1
    docs = _docs(tl)
    assert len(read_ahap(docs["ahap"]).taps) == 10 and len(_primitives(docs["android"])) == 10
    assert len(read_haptic(docs["haptic"]).taps) == 10
    track = read_hjif(docs["hjif"])
    assert not track.taps and track.points


def test_intensity_follows_strength_and_a_bump_without_strength_plays_nothing():
    assert event_intensity(1.0) == 1.0 and event_intensity(0.0) == 0.0
    assert event_intensity(1e-9) == pytest.approx(INTENSITY_FLOOR)
    assert event_intensity(0.5) == pytest.approx(INTENSITY_FLOOR ** 0.5)
    plan = plan_events([BumpEvent(0.1, 0.0, 30.0), BumpEvent(0.3, 0.6, 30.0)], PHONE_TRANSIENT_S)
    assert [e.t_s for e in plan.transients] == [0.3]


def _min_jerk_rows(x0_mm, x1_mm, duration_s, pressure, rate=240.0):
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / rate)
    u = t / duration_s
    x = x0_mm + (x1_mm - x0_mm) * (10 * u**3 - 15 * u**4 + 6 * u**5)
    return [[float(a), float(b), Y_M * 1e3, pressure] for a, b in zip(t, x)]


def test_a_recorded_stroke_carries_one_transient_per_crossing(field):
    img, tmap, surface, profile = field
    rows = _min_jerk_rows(105.0, 138.0, 1.2, 0.5)
    stroke = parse_stroke(rows, "<recorded>", tmap.width_m, tmap.height_m)
    xs = np.array([r[1] for r in rows]) * 1e-3
    ts = np.array([r[0] for r in rows])
    centres = SPARSE_X_M[SPARSE_X_M < 0.137]  # the bumps the path crosses
    tl = run_stroke(stroke, tmap, profile, surface=surface)
    docs = _docs(tl)
    _match_x([tap.t_s for tap in read_ahap(docs["ahap"]).taps], ts, xs, centres)
    _match_x([p["t_ms"] / 1e3 for p in _primitives(docs["android"])], ts, xs, centres)
    _match_x([tap.t_s for tap in read_haptic(docs["haptic"]).taps], ts, xs, centres)
    _match_x([tap.t_s for tap in read_hjif(docs["hjif"]).taps], ts, xs, centres)
    assert all(tap.amplitude == pytest.approx(1.0) for tap in read_ahap(docs["ahap"]).taps)
    # half the reference pressure: half the strength, 10 dB less intensity
    light = [r[:3] + [0.25] for r in rows]
    tl_light = run_stroke(parse_stroke(light, "<light>", tmap.width_m, tmap.height_m), tmap, profile, surface=surface)
    taps = read_ahap(json.loads(render(tl_light, "ahap"))).taps
    assert len(taps) == len(centres)
    assert all(tap.amplitude == pytest.approx(INTENSITY_FLOOR ** 0.5, abs=1e-3) for tap in taps)


def test_the_export_command_carries_the_bumps_of_a_recorded_stroke(tmp_path):
    from PIL import Image

    f = _field()
    png = tmp_path / "bumps.png"
    Image.fromarray(np.round(f.heights * 255).astype(np.uint8)).save(png)
    rows = _min_jerk_rows(105.0, 138.0, 1.2, 0.5)
    csv_path = tmp_path / "stroke.csv"
    csv_path.write_text("t_s,x_mm,y_mm,pressure\n" + "".join(f"{t:.6f},{x:.4f},{y:.4f},{p}\n" for t, x, y, p in rows))
    xs = np.array([r[1] for r in rows]) * 1e-3
    centres = SPARSE_X_M[SPARSE_X_M < 0.137]
    out = tmp_path / "stroke.ahap"
    r = subprocess.run([sys.executable, "-m", "tactilize.cli", "export", str(png), "--stroke", str(csv_path),
                        "--format", "ahap", "--dpi", str(DPI), "-o", str(out), "--json"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["rendering"] == "surface" and doc["transients"] == len(centres) and doc["continuous_runs"] == 0
    _match_x([tap.t_s for tap in read_ahap(out.read_bytes()).taps], np.array([r[0] for r in rows]), xs, centres)


def test_steady_renderings_keep_their_output(field):
    """The paper preset (steady) exports the trains its rendering fired, surface or not: each pulse at
    its drive's strength and frequency, a period of that drive after the one before, and the same
    bytes with or without the picture's surface."""
    from tactilize.export.events import drive_strength

    img, tmap, surface, _ = field
    paper = Profile.preset("paper")
    stroke = synthetic_stroke(tmap.width_m, tmap.height_m, SPEED_M_S, 0.5)
    with_surface = run_stroke(stroke, tmap, paper, start_s=0.0, end_s=0.5, mirror=True, surface=surface)
    without = run_stroke(stroke, tmap, paper, start_s=0.0, end_s=0.5, mirror=True)
    assert with_surface.events == without.events and with_surface.regular
    events = with_surface.events
    assert len(events) > 50
    for a, b in zip(events, events[1:]):
        drive = with_surface.at(b.t_s)
        assert b.frequency_hz == drive.pulse_frequency_hz and b.strength == drive_strength(drive)
        assert b.t_s - a.t_s == pytest.approx(1.0 / b.frequency_hz, rel=1e-6)
    for fmt in ("ahap", "android", "haptic", "hjif"):
        assert render(with_surface, fmt) == render(without, fmt)


def test_a_steady_stroke_that_starts_where_the_drive_is_off_exports_to_android():
    """An envelope point of 0 Hz (the drive off) was refused (android.envelope-values): it takes its neighbour's."""
    off, on = Drive.off(), Drive(120.0, 3e-4)
    nan = float("nan")
    tl = DriveTimeline((0.0, 0.2), 0.6, ((off,), (on,)), ((off,), (on,)), (0.0, 0.05), (nan, nan), (nan, nan))
    doc = json.loads(render(tl, "android"))
    freqs = [c["frequency_hz"] for w in doc["waveform_envelopes"] for c in w["control_points"]]
    assert min(freqs) == 120.0 and doc["waveform_envelopes"][0]["initial_frequency_hz"] == 120.0
    assert doc["waveform_envelopes"][0]["start_ms"] == 200  # silent while the drive is off: it starts with the pulses


def test_the_wire_drive_of_a_surface_stroke_stays_a_drive_over_time(synthetic):
    """``--drive wire`` asks for what the simulated wire applied: the rows, not the bumps."""
    import dataclasses

    rows_only = dataclasses.replace(synthetic, events=None)
    for fmt in ("ahap", "android", "haptic", "hjif"):
        assert render(synthetic, fmt, drive="wire") == render(rows_only, fmt, drive="wire")
        assert render(synthetic, fmt) != render(rows_only, fmt)
