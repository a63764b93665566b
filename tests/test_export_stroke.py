"""Exports that follow a stroke: AHAP rules, frequency with speed, .hjif/.haptic, round trips, bad strokes."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import wave

import numpy as np
import pytest

from tactilize.drive import Drive
from tactilize.export import (
    AHAP_MAX_CURVE_POINTS,
    AHAP_MAX_EVENT_S,
    DriveTimeline,
    StrokeError,
    ahap_document,
    ahap_pattern,
    android_document,
    haptic_document,
    hjif_document,
    intensity_from_drive,
    parse_stroke,
    read_ahap,
    read_haptic,
    read_hjif,
    read_stroke,
    render,
    run_stroke,
    SHARPNESS_HIGH_HZ,
    SHARPNESS_LOW_HZ,
    sharpness_from_frequency,
    stroke_csv,
    stroke_json,
)
from tactilize.export.haptic import HAPTIC_HIGH_HZ, HAPTIC_LOW_HZ
from tactilize.image import load_image
from tactilize.mapping import Profile
from tactilize.mapping.laws import PowerSpeed
from tactilize.maps.texturemap import texture_map

DPI = 100.0
MM_PER_PX = 25.4 / DPI


def tapping_profile() -> Profile:
    """The paper's laws with a speed factor proportional to speed (the paper's sigmoid never falls
    below about 46 Hz here): the accelerating stroke's slow start taps (pulses over 22 ms apart),
    its fast end vibrates (65 Hz and more), and between them pulses come too close for a player
    to tap them apart, so those play continuously too."""
    return dataclasses.replace(Profile.preset("paper"), name="paper-proportional", speed=PowerSpeed(160.0, 1.0))


def two_textures() -> np.ndarray:
    """A 600 x 200 px picture: a 10 mm grating on the left half, a 25 mm one on the right."""
    x = np.arange(600)
    a = np.empty((200, 600))
    a[:, :300] = 0.5 + 0.5 * np.sin(2 * np.pi * x[:300] / 40)
    a[:, 300:] = 0.5 + 0.5 * np.sin(2 * np.pi * x[300:] / 100)
    return a


def accelerating_rows(v0=10.0, v1=150.0, duration=1.5, rate=240.0, x0=2.0, y=25.0):
    """t_s, x_mm, y_mm of a stroke speeding up linearly from v0 to v1 [mm/s] along +x."""
    t = np.arange(0.0, duration, 1.0 / rate)
    acc = (v1 - v0) / duration
    return [[float(ti), float(x0 + v0 * ti + 0.5 * acc * ti * ti), y] for ti in t]


@pytest.fixture(scope="module")
def tmap():
    return texture_map(load_image(two_textures(), dpi=DPI))


@pytest.fixture(scope="module")
def timeline(tmap):
    stroke = parse_stroke(accelerating_rows(), "<test>", tmap.width_m, tmap.height_m)
    return run_stroke(stroke, tmap, Profile.preset("paper"), meta={"image": "two-textures"})


@pytest.fixture(scope="module")
def tapping(tmap):
    """The same stroke with :func:`tapping_profile`: taps, close pulses and continuous vibration."""
    stroke = parse_stroke(accelerating_rows(), "<test>", tmap.width_m, tmap.height_m)
    return run_stroke(stroke, tmap, tapping_profile(), meta={"image": "two-textures"})


def test_the_stroke_crosses_two_textures_and_speeds_up(timeline, tmap):
    # the fixture itself: what the other tests rely on
    assert timeline.x_m[0] < tmap.width_m / 2 < timeline.x_m[-1]
    assert timeline.speed_m_s[2] < 0.03 and timeline.speed_m_s[-1] > 0.13
    f = [d.pulse_frequency_hz for d in timeline.drives()]
    assert min(f) < 65.0 < max(f)  # both taps and continuous vibration
    # the wire's drive is the controller's, not the profile's width
    assert any(w.pulse_width_s != p.pulse_width_s for w, p in zip(timeline.drives("wire"), timeline.drives()))


# ----------------------------------------------------------------- AHAP


def _ahap_parts(doc):
    events = [e["Event"] for e in doc["Pattern"] if "Event" in e]
    curves = [e["ParameterCurve"] for e in doc["Pattern"] if "ParameterCurve" in e]
    return events, curves


def test_ahap_structure_rules_on_the_accelerating_stroke(tapping):
    timeline = tapping  # taps, then a continuous run to the end
    doc = ahap_document(timeline)
    assert doc["Version"] == 1.0 and isinstance(doc["Metadata"], dict)
    for entry in doc["Pattern"]:
        assert len(entry) == 1 and next(iter(entry)) in ("Event", "ParameterCurve")
    events, curves = _ahap_parts(doc)
    kinds = {e["EventType"] for e in events}
    assert kinds == {"HapticTransient", "HapticContinuous"}
    for e in events:
        assert isinstance(e["Time"], float) and e["Time"] >= 0
        params = {p["ParameterID"]: p["ParameterValue"] for p in e["EventParameters"]}
        assert set(params) == {"HapticIntensity", "HapticSharpness"}
        assert all(0.0 <= v <= 1.0 for v in params.values())
        if e["EventType"] == "HapticContinuous":
            assert 0 < e["EventDuration"] <= AHAP_MAX_EVENT_S
        else:
            assert "EventDuration" not in e
    by_id = {}
    for c in curves:
        assert c["ParameterID"] in ("HapticIntensityControl", "HapticSharpnessControl")
        pts = c["ParameterCurveControlPoints"]
        assert 1 <= len(pts) <= AHAP_MAX_CURVE_POINTS
        times = [p["Time"] for p in pts]
        assert times[0] == 0.0 and times == sorted(times)
        lo, hi = (0.0, 1.0) if c["ParameterID"] == "HapticIntensityControl" else (-1.0, 1.0)
        assert all(lo <= p["ParameterValue"] <= hi for p in pts)
        by_id.setdefault(c["ParameterID"], []).append(c)
    # the stroke needs more than 16 points: the curves were split
    assert len(by_id["HapticIntensityControl"]) >= 2 and len(by_id["HapticSharpnessControl"]) >= 2
    # after the continuous run nothing is left scaled: the last curves are neutral
    # (or end where the pattern ends); the run lasts from its first pulse to one interval after
    # its last (the pen lifts at the stroke's last sample: nothing fires after it)
    from tactilize.export.events import PHONE_TRANSIENT_S, plan_events, timeline_events

    cont = [e for e in events if e["EventType"] == "HapticContinuous"]
    (run,) = plan_events(timeline_events(timeline), PHONE_TRANSIENT_S, timeline.end_s).runs
    assert cont[0]["Time"] == pytest.approx(run.start_s, abs=1e-6)
    assert sum(e["EventDuration"] for e in cont) == pytest.approx(run.end_s - run.start_s, abs=1e-5)
    assert run.events[-1].t_s < run.end_s <= timeline.end_s


def test_ahap_sharpness_control_is_neutral_so_the_event_sharpness_plays():
    # the old bug: a sharpness control of 1.0 is *added*, so every event played at 1.0
    d = Drive(182.5, 0.4e-3, 1.0)
    events, curves = _ahap_parts(ahap_pattern(d, 2.0))
    sharp = [c for c in curves if c["ParameterID"] == "HapticSharpnessControl"]
    inten = [c for c in curves if c["ParameterID"] == "HapticIntensityControl"]
    assert all(p["ParameterValue"] == 0.0 for c in sharp for p in c["ParameterCurveControlPoints"])
    assert all(p["ParameterValue"] == 1.0 for c in inten for p in c["ParameterCurveControlPoints"])
    track = read_ahap(ahap_pattern(d, 2.0))
    assert all(p.frequency_hz == pytest.approx(182.5, rel=1e-3) for p in track.points)


def test_ahap_effective_sharpness_stays_below_one_on_the_stroke(timeline):
    track = read_ahap(ahap_document(timeline))
    # what a phone plays: event sharpness + control, clamped; 300 Hz is the only 1.0
    assert max(sharpness_from_frequency(p.frequency_hz) for p in track.points) == pytest.approx(1.0)
    for p in track.points:
        expected = [sharpness_from_frequency(_value_at(timeline, p.t_s + dt)[1]) for dt in (-1e-3, 0.0, 1e-3)]
        assert min(abs(sharpness_from_frequency(p.frequency_hz) - e) for e in expected) <= 0.01


# ----------------------------------------------------------------- round trips


def _events_curve(tl, min_interval_s=0.020):
    """The stroke's one events timeline (what every parametric format plays) as curves:
    (times, intensities, local rates), the rate of each run of events closer than
    ``min_interval_s`` over that run, as the continuous stretches follow them."""
    from tactilize.export.events import close_groups, event_intensity, timeline_events
    from tactilize.surface.events import local_rate_hz

    evs = timeline_events(tl)
    t = np.array([e.t_s for e in evs])
    rate = np.concatenate([local_rate_hz(np.array([e.t_s for e in g])) for g in close_groups(evs, min_interval_s)])
    return t, np.array([event_intensity(e.strength) for e in evs]), rate


def _value_at(tl, t, min_interval_s=0.020):
    """Intensity and rate of the events at ``t`` [s] (a steady stroke's: its pulses, at their
    drive's intensity and their train's rate)."""
    times, inten, rate = _events_curve(tl, min_interval_s)
    return float(np.interp(t, times, inten)), float(np.interp(t, times, rate))


def _close_to_drive(tl, p, *, fmin=0.0, fmax=np.inf, min_interval_s=0.020):
    """The point matches the events at its time or 1 ms either side (timing within 1 ms)."""
    for t in (p.t_s, p.t_s - 1e-3, p.t_s + 1e-3):
        a, f = _value_at(tl, t, min_interval_s)
        f_ok = not (fmin <= f <= fmax) or abs(p.frequency_hz - f) <= 0.01 * f
        if abs(p.amplitude - a) <= 0.02 and f_ok:
            return True
    return False


def _expected_taps(tl, min_interval_s):
    """The events at least ``min_interval_s`` from the one before and after: those a player
    plays apart as taps (closer ones play continuously)."""
    from tactilize.export.events import plan_events, timeline_events

    return list(plan_events(timeline_events(tl), min_interval_s, tl.end_s).transients)


def _check_taps(tl, track, min_interval_s, with_frequency=True, fmin=0.0, fmax=np.inf):
    """Taps where the rule puts them, at the event's intensity (a steady pulse's: its drive's,
    the same rule as a continuous stretch); frequencies as the format can say them (clipped
    to its range, whole hertz in .hjif)."""
    from tactilize.export.events import event_intensity, timeline_events

    taps, expected = track.taps, _expected_taps(tl, min_interval_s)
    assert len(taps) == len(expected)
    for tap, ev in zip(taps, expected):
        assert abs(tap.t_s - ev.t_s) <= 1e-3
        assert tap.amplitude == pytest.approx(event_intensity(ev.strength), abs=0.02)
        if with_frequency:
            f = min(max(ev.frequency_hz, fmin), fmax)
            assert tap.frequency_hz == pytest.approx(f, rel=0.01, abs=0.5)
    gaps = np.diff([t.t_s for t in taps])
    assert np.all(gaps >= min_interval_s - 1e-3)  # (times in whole milliseconds)
    slow = [e for e in timeline_events(tl) if e.frequency_hz < 65.0]
    close = [e for e in slow if e not in expected]
    return len(expected), len(close)


@pytest.mark.parametrize("which", ["timeline", "tapping"])
def test_round_trip_ahap(which, request):
    tl = request.getfixturevalue(which)
    track = read_ahap(json.loads(render(tl, "ahap")))
    assert len(track.points) > 20
    # AHAP's sharpness says 65 .. 300 Hz: a continuous stretch below 65 Hz reads back as 65 Hz
    assert all(_close_to_drive(tl, p, fmin=SHARPNESS_LOW_HZ, fmax=SHARPNESS_HIGH_HZ) for p in track.points)
    taps, close = _check_taps(tl, track, 0.020, with_frequency=False)  # AHAP taps carry no frequency of their own
    if which == "tapping":
        assert taps > 5 and close > 5
        # ...the train's frequency is in their spacing
        first, second = _expected_taps(tl, 0.020)[:2]
        assert track.taps[0].frequency_hz == pytest.approx(1.0 / (second.t_s - first.t_s), rel=0.02)
    else:
        # The paper's law keeps this stroke at 46 Hz and more: pulses under 22 ms apart, no taps.
        assert taps == 0 and close > 0


@pytest.mark.parametrize("which", ["timeline", "tapping"])
def test_round_trip_hjif(which, request):
    tl = request.getfixturevalue(which)
    doc = json.loads(render(tl, "hjif"))
    for c in range(2):
        track = read_hjif(doc, channel=c)
        assert track.channels == 2 and len(track.points) > 20
        assert all(_close_to_drive(tl, p, min_interval_s=0.022) for p in track.points)
        taps, close = _check_taps(tl, track, 0.022)
        assert (taps > 5 and close > 5) if which == "tapping" else (taps == 0 and close > 0)


@pytest.mark.parametrize("which", ["timeline", "tapping"])
def test_round_trip_haptic(which, request):
    tl = request.getfixturevalue(which)
    track = read_haptic(render(tl, "haptic"))
    assert len(track.points) > 20
    assert all(_close_to_drive(tl, p, fmin=HAPTIC_LOW_HZ, fmax=HAPTIC_HIGH_HZ) for p in track.points)
    taps, close = _check_taps(tl, track, 0.020, fmin=HAPTIC_LOW_HZ, fmax=HAPTIC_HIGH_HZ)
    assert (taps > 5 and close > 5) if which == "tapping" else (taps == 0 and close > 0)


def _wave_spans_ms(doc, channel):
    """(start, end) [ms] of each VectorialWave effect of a .hjif channel."""
    (perc,) = doc["perceptions"]
    out = []
    for band in perc["channels"][channel]["bands"]:
        if band["band_type"] == "VectorialWave":
            out += [(e["position"], e["position"] + e["keyframes"][-1]["relative_position"]) for e in band["effects"]]
    return out


@pytest.mark.parametrize("profile", ["paper", "perceptual", "physical"])
def test_no_player_gets_taps_closer_than_it_plays_them_apart(profile):
    """The MPEG reference synthesiser plays a transient over 22 ms and a phone's actuator needs 20 ms:
    closer taps overlap and smear (found running the reference software on a physical-profile
    sandpaper stroke: 47 of 82 gaps under 22 ms).  Pulses that close play in a wave instead."""
    from tactilize.data import builtin_map
    from tactilize.export import synthetic_stroke

    tmap = builtin_map("sandpaper")
    stroke = synthetic_stroke(tmap.width_m, tmap.height_m, 0.050, 2.0)
    tl = run_stroke(stroke, tmap, Profile.preset(profile), start_s=0.0, end_s=2.0, mirror=True)
    from tactilize.export.events import timeline_events

    slow = [e.t_s for e in timeline_events(tl) if e.frequency_hz < 65.0]
    doc = json.loads(render(tl, "hjif"))
    for c in range(2):
        (perc,) = doc["perceptions"]
        taps = [e["position"] for b in perc["channels"][c]["bands"] if b["band_type"] == "Transient"
                for e in b["effects"]]
        assert all(b - a >= 22 for a, b in zip(taps, taps[1:])), np.diff(taps).min()
        # every slow pulse is played: a tap at its millisecond or inside a wave
        spans = _wave_spans_ms(doc, c)
        tapped = set(taps)
        # (positions are whole milliseconds)
        assert all(round(t * 1e3) in tapped or any(a - 1 <= t * 1e3 <= b + 1 for a, b in spans) for t in slow)
    for fmt, read in (("ahap", lambda d: read_ahap(json.loads(d))), ("haptic", read_haptic)):
        taps = [t.t_s for t in read(render(tl, fmt)).taps]
        assert all(b - a >= 0.020 - 1e-6 for a, b in zip(taps, taps[1:])), (fmt, np.diff(taps).min())
    if profile == "physical":
        assert len(slow) > 50  # the case that overlapped: most pulses under 65 Hz


@pytest.mark.parametrize("hz, phone_taps, hjif_taps", [(50.0, True, False), (1 / 0.022, True, True), (55.0, False, False)])
def test_a_train_exactly_at_a_players_interval_is_all_taps(hz, phone_taps, hjif_taps):
    """20 ms apart is a phone's interval, 22 ms the .hjif one: a train exactly there is all taps,
    not a mix that float rounding picks (14 of 49 gaps of a 50 Hz train read as closer before)."""
    tl = DriveTimeline.steady(Drive(hz, 0.5e-3, 1.0), 1.0)
    n = len(tl.pulses())
    ahap = ahap_document(tl)
    transients = [e for e in ahap["Pattern"] if e.get("Event", {}).get("EventType") == "HapticTransient"]
    assert len(transients) == (n if phone_taps else 0)
    assert len(read_haptic(render(tl, "haptic")).taps) == (n if phone_taps else 0)
    assert len(read_hjif(hjif_document(tl)).taps) == (n if hjif_taps else 0)
    # no two curves of one parameter at one time (spans that touch are one span)
    keys = [(c["ParameterCurve"]["ParameterID"], c["ParameterCurve"]["Time"]) for c in ahap["Pattern"]
            if "ParameterCurve" in c]
    assert len(keys) == len(set(keys))


def test_frequency_rises_with_speed_in_every_format_that_carries_it(timeline):
    series = {
        "ahap": [p.frequency_hz for p in read_ahap(ahap_document(timeline)).points],
        "hjif": [p.frequency_hz for p in read_hjif(hjif_document(timeline)).points],
        "haptic": [p.frequency_hz for p in read_haptic(haptic_document(timeline)).points],
        "android": [c["frequency_hz"] for c in android_document(timeline)["envelope"]],
    }
    assert all(np.all(np.diff(timeline.speed_m_s[2:]) > -1e-3) for _ in [0])  # the stroke only speeds up
    for name, f in series.items():
        f = np.asarray(f)
        assert len(f) > 5, name
        assert np.all(np.diff(f) >= -0.01 * f[1:]), name
        assert f[-1] > 1.5 * f[0], name


# ----------------------------------------------------------------- .hjif and .haptic fields


def test_hjif_field_names_and_types(tapping):
    doc = json.loads(render(tapping, "hjif"))
    assert set(doc) == {"version", "profile", "level", "date", "description", "timescale", "avatars", "perceptions", "syncs"}
    assert doc["profile"] in ("Main", "Simple Parametric") and isinstance(doc["timescale"], int) and doc["timescale"] == 1000
    # id 0 is reserved for "unspecified" (the MPEG reference reader refuses it); the perception names it
    assert doc["avatars"] == [{"id": 1, "lod": 0, "type": "Vibration"}]
    (perc,) = doc["perceptions"]
    assert perc["avatar_id"] == 1 and perc["reference_devices"][0]["id"] == 1
    assert {"id", "avatar_id", "description", "perception_modality", "effect_library", "channels",
            "reference_devices"} <= set(perc)
    assert perc["perception_modality"] == "Vibrotactile"
    dev = perc["reference_devices"][0]
    assert dev["minimum_frequency"] < dev["maximum_frequency"]
    assert [c["id"] for c in perc["channels"]] == [0, 1]
    for ch in perc["channels"]:
        assert {"id", "description", "gain", "mixing_coefficient", "body_part_mask", "bands"} <= set(ch)
        assert {b["band_type"] for b in ch["bands"]} == {"VectorialWave", "Transient"}
        for band in ch["bands"]:
            assert isinstance(band["lower_frequency_limit"], int) and isinstance(band["upper_frequency_limit"], int)
            assert band["lower_frequency_limit"] < band["upper_frequency_limit"]
            for eff in band["effects"]:
                assert eff["effect_type"] in ("Basis", "Reference", "Composite")
                assert eff["base_signal"] in ("Sine", "Square", "Triangle", "SawToothUp", "SawToothDown")
                assert isinstance(eff["position"], int) and isinstance(eff["phase"], float)
                for kf in eff["keyframes"]:
                    assert set(kf) == {"relative_position", "amplitude_modulation", "frequency_modulation"}
                    assert isinstance(kf["relative_position"], int) and kf["relative_position"] >= 0
                    assert 0.0 <= kf["amplitude_modulation"] <= 1.0
                    # the reference reader takes only an integer: a fractional frequency would play silence
                    assert isinstance(kf["frequency_modulation"], int)
                    assert band["lower_frequency_limit"] <= kf["frequency_modulation"] <= band["upper_frequency_limit"]


def test_haptic_field_names_and_types(timeline):
    doc = json.loads(render(timeline, "haptic"))
    assert set(doc["version"]) == {"major", "minor", "patch"} and all(isinstance(v, int) for v in doc["version"].values())
    assert isinstance(doc["metadata"], dict)
    env = doc["signals"]["continuous"]["envelopes"]
    assert set(env) == {"amplitude", "frequency"}
    for p in env["amplitude"]:
        assert {"time", "amplitude"} <= set(p) <= {"time", "amplitude", "emphasis"}
        assert isinstance(p["time"], float) and 0.0 <= p["amplitude"] <= 1.0
        if "emphasis" in p:
            assert set(p["emphasis"]) == {"amplitude", "frequency"}
    for p in env["frequency"]:
        assert set(p) == {"time", "frequency"} and 0.0 <= p["frequency"] <= 1.0
    times = [p["time"] for p in env["amplitude"]]
    assert all(b > a for a, b in zip(times, times[1:]))  # breakpoint times increase
    assert times == [p["time"] for p in env["frequency"]]


# ----------------------------------------------------------------- Android, WAV, drive log


def test_android_envelopes_within_the_documented_limits(timeline):
    doc = android_document(timeline)
    assert doc["waveform_envelopes"] and doc["basic_envelopes"]
    for env in doc["waveform_envelopes"]:
        assert 1 <= len(env["control_points"]) <= 16
        for c in env["control_points"]:
            assert 20 <= c["duration_ms"] <= 1000 and 0.0 <= c["amplitude"] <= 1.0
    # the envelopes play the stroke's pulses: from the first one fired to one interval after the last
    from tactilize.export.events import PHONE_TRANSIENT_S, plan_events, timeline_events

    runs = plan_events(timeline_events(timeline), PHONE_TRANSIENT_S, timeline.end_s).runs
    total = sum(c["duration_ms"] for env in doc["waveform_envelopes"] for c in env["control_points"])
    assert abs(total - sum(r.end_s - r.start_s for r in runs) * 1e3) <= 1
    for env in doc["basic_envelopes"]:
        assert len(env["control_points"]) <= 16 and env["control_points"][-1]["intensity"] == 0.0
        assert all(20 <= c["duration_ms"] <= 1000 for c in env["control_points"])
    assert sum(doc["timings_ms"]) == round(timeline.end_s * 1e3) and len(doc["timings_ms"]) == len(doc["amplitudes"])
    assert all(0 <= a <= 255 for a in doc["amplitudes"]) and "WaveformEnvelopeBuilder" in doc["kotlin"]


def test_wav_of_the_stroke_is_48k_two_channels(timeline, tmp_path):
    p = tmp_path / "s.wav"
    p.write_bytes(render(timeline, "wav"))
    with wave.open(str(p)) as w:
        assert w.getframerate() == 48_000 and w.getnchannels() == 2
        assert w.getnframes() == round(timeline.end_s * 48_000)
        x = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").reshape(-1, 2)
    edges = np.flatnonzero(np.diff((x[:, 0] > 0).astype(int)) == 1) + 1
    rises = edges.size + int(x[0, 0] > 0)
    assert rises == len(timeline.pulses())
    # the WAV carries frequency in its pulse spacing: it rises with the speed
    rate = 48_000 / np.diff(edges)
    assert np.mean(rate[-5:]) > 2 * np.mean(rate[:5])
    assert np.all(np.diff(rate) > -0.05 * rate[1:])  # within a sample of rounding


def test_drive_log_has_one_row_per_drive_change(timeline):
    doc = json.loads(render(timeline, "json"))
    rows = doc["rows"]
    assert len(rows) == len(timeline.changes()) and doc["format"] == "tactilize-drive-log"
    keys = [k for k in rows[0] if k.startswith("ch")]
    assert all(any(a[k] != b[k] for k in keys) for a, b in zip(rows, rows[1:]))
    csv_lines = render(timeline, "log").decode().splitlines()
    assert len(csv_lines) == len(rows) + 1
    wire = json.loads(render(timeline, "json", drive="wire"))
    assert wire["drive"] == "wire" and wire["rows"][0]["ch0_pulse_width_s"] != rows[0]["ch0_pulse_width_s"]


# ----------------------------------------------------------------- stroke files


def test_stroke_files_round_trip(tmap, tmp_path):
    s = parse_stroke([[0.0, 1.0, 2.0, 0.5], [0.01, 1.5, 2.0, None]], "<t>", tmap.width_m, tmap.height_m)
    for data in (stroke_csv(s), stroke_json(s)):
        back = read_stroke(data, tmap.width_m, tmap.height_m)
        assert back.t_s == pytest.approx(s.t_s) and back.x_m == pytest.approx(s.x_m) and back.pressure == s.pressure


@pytest.mark.parametrize(
    "text, fault",
    [
        ("", "empty"),
        ("t_s,x_mm,y_mm\n", "empty"),
        ("t_s,x_mm,y_mm\n0,1,1\n0.02,2,1\n0.01,3,1\n", "times must increase"),
        ("t_s,x_mm,y_mm\n0,1,1\n0.01,nan,1\n", "not a finite number"),
        ("t_s,x_mm,y_mm\n0,1,1\n0.01,900,1\n", "outside the picture"),
        ('{"samples": [{"t_s": 0, "x_mm": 1, "y_mm": -1}]}', "outside the picture"),
        ("[]", "empty"),
    ],
)
def test_bad_stroke_files_one_line_exit_2(tmp_path, text, fault):
    img = tmp_path / "two.png"
    from PIL import Image

    Image.fromarray((two_textures() * 255).astype("uint8")).save(img, dpi=(DPI, DPI))
    stroke = tmp_path / "stroke.csv"
    stroke.write_text(text)
    with pytest.raises(StrokeError, match=fault):
        read_stroke(stroke, 0.1524, 0.0508)
    proc = subprocess.run(
        [sys.executable, "-m", "tactilize.cli", "export", str(img), "--stroke", str(stroke), "--format", "ahap",
         "-o", str(tmp_path / "o.ahap")],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tactilize: ") and fault in lines[0]
    assert not (tmp_path / "o.ahap").exists()


def test_cli_exports_a_recorded_stroke(tmp_path, tmap):
    from click.testing import CliRunner
    from PIL import Image

    from tactilize.cli import main

    img = tmp_path / "two.png"
    Image.fromarray((two_textures() * 255).astype("uint8")).save(img, dpi=(DPI, DPI))
    s = parse_stroke(accelerating_rows(), "<t>", tmap.width_m, tmap.height_m)
    (tmp_path / "s.csv").write_bytes(stroke_csv(s))
    out = tmp_path / "s.hjif"
    res = CliRunner().invoke(main, ["export", str(img), "--stroke", str(tmp_path / "s.csv"), "--format", "hjif",
                                    "-o", str(out), "--json", "--profile", "paper"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["min_frequency_hz"] < 65 < doc["max_frequency_hz"] and doc["drive_changes"] > 20
    track = read_hjif(out.read_bytes())
    assert max(p.frequency_hz for p in track.points) == pytest.approx(doc["max_frequency_hz"], rel=0.01)


def test_steady_timeline_is_refused_when_malformed():
    from tactilize.errors import SignalError

    with pytest.raises(SignalError, match="finite"):
        DriveTimeline.steady(Drive(100.0, 1e-3), float("nan"))
    with pytest.raises(SignalError, match="increase"):
        DriveTimeline((0.0, 0.0), 1.0, ((Drive.off(),),) * 2, ((Drive.off(),),) * 2, (0.0,) * 2, (0.0,) * 2, (0.0,) * 2)


def test_a_synthetic_stroke_longer_than_the_picture_stays_steady(tmap):
    from tactilize.export import synthetic_stroke

    # 3 s at 60 mm/s is 180 mm on a 152 mm picture, diagonally: it crosses edges
    s = synthetic_stroke(tmap.width_m, tmap.height_m, 0.060, 3.0, direction_deg=30.0)
    tl = run_stroke(s, tmap, Profile.preset("paper"), start_s=0.0, end_s=3.0, mirror=True)
    assert tl.end_s == 3.0 and tl.t_s[0] == 0.0
    assert np.allclose(tl.speed_m_s, 0.060, rtol=0.01)
    assert all(not d.is_off for d in tl.drives())
    assert max(tl.x_m) > tmap.width_m or min(tl.y_m) < 0  # it did run past an edge


def test_ahap_of_a_long_sweep_splits_events_and_curves_and_reads_back():
    # 70 s of drive rising 80 -> 280 Hz in half-second steps: three events, many curves
    t = tuple(0.5 * k for k in range(140))
    drives = tuple((Drive(80.0 + 200.0 * k / 139, 0.3e-3, 0.5 + 0.5 * k / 139),) for k in range(140))
    nan = (float("nan"),) * 140
    tl = DriveTimeline(t, 70.0, drives, drives, (0.0,) * 140, nan, nan)
    doc = ahap_document(tl)
    events, curves = _ahap_parts(doc)
    assert [e["EventDuration"] for e in events] == [30.0, 30.0, 10.0]
    assert all(len(c["ParameterCurveControlPoints"]) <= AHAP_MAX_CURVE_POINTS for c in curves)
    for c in curves:  # every curve lies inside one event
        start = c["Time"]
        end = start + c["ParameterCurveControlPoints"][-1]["Time"]
        assert any(e["Time"] - 1e-6 <= start and end <= e["Time"] + e["EventDuration"] + 1e-6 for e in events)
    track = read_ahap(doc)
    assert all(_close_to_drive(tl, p) for p in track.points)
    f = [p.frequency_hz for p in track.points]
    assert np.all(np.diff(f) >= -0.01 * np.asarray(f[1:])) and f[-1] > 3 * f[0]
