"""Exports parse back: WAV rate and length, CSV samples, JSON, AHAP keys, Android timings."""

from __future__ import annotations

import csv
import json
import math
import wave

import numpy as np
import pytest

from tactilize.errors import SignalError
from tactilize.export import (
    FORMATS,
    ahap_pattern,
    android_waveform,
    export,
    export_ahap,
    export_android,
    export_csv,
    export_json,
    export_wav,
    intensity_from_drive,
    sharpness_from_frequency,
)
from tactilize.mapping import Drive


def test_wav_reads_back_with_rate_length_and_pulses(tmp_path):
    d = Drive(120.0, 0.5e-3, 0.5)
    p = export_wav(d, tmp_path / "x.wav", duration_s=1.5)
    with wave.open(str(p)) as w:
        assert w.getframerate() == 48_000
        assert w.getnframes() == 72_000
        assert w.getnchannels() == 1 and w.getsampwidth() == 2
        x = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2")
    # 1.5 s at 120 Hz: 180 pulses of 24 samples at half scale
    on = x > 0
    assert int(np.count_nonzero(np.diff(on.astype(int)) == 1)) + int(on[0]) == 180
    assert int(np.count_nonzero(on)) == 180 * 24
    assert set(np.unique(x)) == {0, round(0.5 * 32767)}


def test_wav_two_channels(tmp_path):
    p = export_wav([Drive(100.0, 1e-3, 1.0), Drive(50.0, 2e-3, 0.25)], tmp_path / "x.wav", duration_s=0.2)
    with wave.open(str(p)) as w:
        assert w.getnchannels() == 2
        x = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").reshape(-1, 2)
    assert np.count_nonzero(x[:, 0]) == 20 * 48 and np.count_nonzero(x[:, 1]) == 10 * 96
    assert x[:, 1].max() == round(0.25 * 32767)


def test_csv_reads_back(tmp_path):
    p = export_csv(Drive(200.0, 0.25e-3, 0.8), tmp_path / "x.csv", duration_s=0.05)
    with open(p, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time_s", "channel_0"]
    body = np.array(rows[1:], dtype=float)
    assert body.shape == (2400, 2)
    assert body[1, 0] == pytest.approx(1 / 48_000)
    assert np.count_nonzero(body[:, 1]) == 10 * 12
    assert body[:, 1].max() == pytest.approx(0.8, rel=1e-6)


def test_json_carries_the_drive_and_extras(tmp_path):
    d = Drive(150.0, 0.3e-3, 0.9, ("max_frequency_hz",))
    p = export_json(d, tmp_path / "x.json", 3.0, image="cloth.png", speed_mm_s=60.0)
    doc = json.loads(p.read_text())
    assert doc["duration_s"] == 3.0 and doc["image"] == "cloth.png" and doc["speed_mm_s"] == 60.0
    ch = doc["channels"][0]
    assert ch["pulse_frequency_hz"] == 150.0 and ch["pulse_width_s"] == 0.3e-3
    assert ch["duty_ratio"] == pytest.approx(0.045) and ch["clamped"] == ["max_frequency_hz"]


def test_ahap_continuous_has_the_documented_keys(tmp_path):
    d = Drive(182.5, 0.4e-3, 1.0)  # halfway up 65 .. 300 Hz
    p = export_ahap(d, tmp_path / "x.ahap", duration_s=2.0)
    doc = json.loads(p.read_text())
    assert doc["Version"] == 1.0
    events = [e["Event"] for e in doc["Pattern"] if "Event" in e]
    curves = [e["ParameterCurve"] for e in doc["Pattern"] if "ParameterCurve" in e]
    assert len(events) == 1
    ev = events[0]
    assert ev["EventType"] == "HapticContinuous" and ev["Time"] == 0.0 and ev["EventDuration"] == 2.0
    params = {q["ParameterID"]: q["ParameterValue"] for q in ev["EventParameters"]}
    assert set(params) == {"HapticIntensity", "HapticSharpness"}
    assert params["HapticSharpness"] == pytest.approx(0.5, abs=1e-3)
    # the fundamental of a 7.3 % duty train relative to a 10 % one
    assert params["HapticIntensity"] == pytest.approx(math.sin(math.pi * 0.073) / math.sin(math.pi * 0.1), abs=1e-3)
    assert {c["ParameterID"] for c in curves} == {"HapticIntensityControl", "HapticSharpnessControl"}
    for c in curves:
        assert "Time" in c and c["ParameterCurveControlPoints"][-1]["Time"] == 2.0


def test_ahap_low_frequency_is_one_transient_per_pulse():
    doc = ahap_pattern(Drive(20.0, 2e-3, 0.7), 0.5)
    events = [e["Event"] for e in doc["Pattern"]]
    assert [e["EventType"] for e in events] == ["HapticTransient"] * 10
    assert [e["Time"] for e in events] == pytest.approx([k * 0.05 for k in range(10)])
    assert all({q["ParameterID"] for q in e["EventParameters"]} == {"HapticIntensity", "HapticSharpness"} for e in events)


def test_ahap_splits_long_continuous_events():
    events = [e["Event"] for e in ahap_pattern(Drive(100.0, 0.5e-3), 70.0)["Pattern"] if "Event" in e]
    assert [e["EventDuration"] for e in events] == [30.0, 30.0, 10.0]


def test_sharpness_and_intensity_maps():
    assert sharpness_from_frequency(65.0) == 0.0
    assert sharpness_from_frequency(300.0) == 1.0
    assert sharpness_from_frequency(1000.0) == 1.0
    assert intensity_from_drive(Drive(100.0, 1e-3)) == pytest.approx(1.0)  # 10 % duty: full
    assert intensity_from_drive(Drive.off()) == 0.0


def test_android_low_frequency_pulses_in_whole_ms(tmp_path):
    p = export_android(Drive(40.0, 3e-3, 0.6), tmp_path / "a.json", duration_s=1.0)
    doc = json.loads(p.read_text())
    t, a = doc["timings_ms"], doc["amplitudes"]
    assert len(t) == len(a) and doc["repeat"] == -1
    assert sum(t) == 1000
    assert all(isinstance(x, int) and x > 0 for x in t)
    assert all(0 <= x <= 255 for x in a)
    # One document for every rendering: each pulse of the 40 Hz train (25 ms apart: a phone
    # plays them apart) is a tap, at the drive's intensity (the rule of a continuous stretch
    # too), TAP_MS on in the fallback; in the compositions one primitive each, 25 ms apart.
    level = round(255 * intensity_from_drive(Drive(40.0, 3e-3, 0.6)))
    assert a.count(level) == 40
    assert t[:2] == [10, 15]
    prims = [q for c in doc["compositions"] for q in c["primitives"]]
    assert len(prims) == 40 and [q["t_ms"] for q in prims] == [25 * k for k in range(40)]
    assert all(q["delay_ms"] == 25 for q in prims[1:])


def test_android_drift_free_with_a_fractional_period():
    w = android_waveform(Drive(30.0, 2e-3), 3.0)
    # pulse k starts at round(k * 33.33 ms): rebuild the starts from the timings
    t, a = w["timings_ms"], w["amplitudes"]
    starts, clock = [], 0
    for dt, amp in zip(t, a):
        if amp > 0:
            starts.append(clock)
        clock += dt
    assert starts == [int(round(k * 1000 / 30)) for k in range(90)]


def test_android_high_frequency_is_one_level():
    w = android_waveform(Drive(250.0, 0.2e-3, 1.0), 2.0)
    assert w["timings_ms"] == [2000]
    assert w["amplitudes"] == [round(255 * intensity_from_drive(Drive(250.0, 0.2e-3)))]


def test_export_dispatch_and_bad_input(tmp_path):
    for fmt in FORMATS:
        assert export(Drive(100.0, 0.5e-3), tmp_path / f"x.{fmt}", fmt, 0.5).exists()
    with pytest.raises(SignalError):
        export(Drive(100.0, 0.5e-3), tmp_path / "x.mp3", "mp3")
    with pytest.raises(SignalError):
        export_wav(Drive(100.0, 0.5e-3), tmp_path / "missing" / "x.wav")
    with pytest.raises(SignalError):
        export_json(Drive(100.0, 0.5e-3), tmp_path / "x.json", duration_s=float("nan"))
