"""The WAV of a stroke on a surface carries the tip's acceleration (synthetic and recorded strokes)."""

from __future__ import annotations

import json
import subprocess
import sys
import wave

import numpy as np
import pytest
from PIL import Image

from tactilize.export import parse_stroke, render, stroke_csv
from tactilize.export.wav import StrokeAcceleration
from tactilize.surface import surface_model
from tactilize.synthesis.acceleration import spectral_peak_hz, spectrum

WIDTH_MM = 64.0  # 256 px: 0.25 mm a pixel
PERIOD_PX = 4  # a 1 mm grating


@pytest.fixture(scope="module")
def grating_png(tmp_path_factory):
    x = np.arange(256)
    row = 0.5 + 0.5 * np.cos(2 * np.pi * x / PERIOD_PX)
    img = np.tile(np.round(row * 255).astype(np.uint8), (128, 1))
    p = tmp_path_factory.mktemp("wav") / "grating.png"
    Image.fromarray(img).save(p)
    return p


def _cli(*args):
    r = subprocess.run([sys.executable, "-m", "tactilize.cli", "export", *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r


def _read(path):
    with wave.open(str(path)) as w:
        assert w.getframerate() == 48_000 and w.getnchannels() == 2 and w.getsampwidth() == 2
        return np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").reshape(-1, 2).astype(float) / 32767


def test_synthetic_stroke_wav_is_the_acceleration_peaking_at_v_fs(grating_png, tmp_path):
    out = tmp_path / "s.wav"
    r = _cli(grating_png, "--speed", 80, "--duration", 1.0, "--format", "wav", "--width-mm", WIDTH_MM, "-o", out,
             "--json")
    doc = json.loads(r.stdout)
    x = _read(out)
    assert doc["signal"] == "tip_acceleration" and doc["clipped_samples"] == 0
    assert doc["peak_full_scale"] == pytest.approx(np.abs(x).max(), abs=1e-4)
    assert x.shape[0] == 48_000
    assert x[:, 0].min() < -0.01 and x[:, 0].max() > 0.01  # signed: an acceleration, not a pulse train
    np.testing.assert_array_equal(x[:, 0], x[:, 1])
    f, p = spectrum(x[:, 0], 48_000)
    assert spectral_peak_hz(f, p) == pytest.approx(80.0, rel=0.03)  # 80 mm/s over 1 mm


def test_recorded_stroke_wav_follows_speed_and_pressure(grating_png, tmp_path):
    # 40 mm/s for 0.5 s, then 120 mm/s for 0.25 s; pressure 0.25 (half strength) throughout.
    t = np.arange(0.0, 0.75, 1 / 240)
    x_mm = np.where(t < 0.5, 5 + 40 * t, 25 + 120 * (t - 0.5))
    rows = [[float(a), float(b), 20.0, 0.25] for a, b in zip(t, x_mm)]
    path = tmp_path / "stroke.csv"
    path.write_bytes(stroke_csv(parse_stroke(rows, "<t>")))
    out = tmp_path / "r.wav"
    _cli(grating_png, "--stroke", path, "--format", "wav", "--width-mm", WIDTH_MM, "-o", out)
    x = _read(out)[:, 0]
    slow, fast = x[2400:21600], x[26400:34800]
    for seg, hz in ((slow, 40.0), (fast, 120.0)):
        f, p = spectrum(seg, 48_000, resolution_hz=4.0)
        assert spectral_peak_hz(f, p) == pytest.approx(hz, rel=0.06)
    # v^2: three times the speed, nine times the acceleration.
    assert np.sqrt(np.mean(fast**2)) / np.sqrt(np.mean(slow**2)) == pytest.approx(9.0, rel=0.1)


def test_pressure_halves_the_wav(grating_png):
    from tactilize.image import load_image

    surface = surface_model(load_image(str(grating_png), width_mm=WIDTH_MM))
    t = np.arange(0.0, 0.5, 1 / 240)
    rows = [[float(a), 5 + 60 * float(a), 20.0, None] for a in t]
    full = parse_stroke(rows, "<t>")
    half = parse_stroke([r[:3] + [0.25] for r in rows], "<t>")
    a = StrokeAcceleration(full, surface, 0.0, 0.45).samples(48_000)[0][:, 0]
    b = StrokeAcceleration(half, surface, 0.0, 0.45).samples(48_000)[0][:, 0]
    np.testing.assert_allclose(b, 0.5 * a, atol=1e-9)
    wav = render(StrokeAcceleration(full, surface, 0.0, 0.45), "wav")
    assert wav[:4] == b"RIFF" and len(wav) == 44 + 4 * round(0.45 * 48_000)


def test_profile_report_audio_rows_peak_at_v_fs(grating_png):
    import json

    r = subprocess.run([sys.executable, "-m", "tactilize.cli", "profile", "report", "--image", str(grating_png),
                        "--width-mm", str(WIDTH_MM), "--no-wire", "--audio", "--json"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rows = json.loads(r.stdout)["audio"]
    assert [row["speed_mm_s"] for row in rows] == [10.0, 20.0, 40.0, 60.0, 100.0, 160.0]
    for row in rows:
        if row["speed_mm_s"] >= 20:  # 10 mm/s on a 1 mm grating is 10 Hz, below the band
            assert row["peak_hz"] == pytest.approx(row["speed_mm_s"], rel=0.05)  # v f_s, f_s = 1 /mm
    rms = {row["speed_mm_s"]: row["rms_full_scale"] for row in rows}
    assert rms[100.0] / rms[40.0] == pytest.approx(6.25, rel=0.1)  # v^2
    text = subprocess.run([sys.executable, "-m", "tactilize.cli", "profile", "report", "--image", str(grating_png),
                           "--width-mm", str(WIDTH_MM), "--no-wire", "--audio"], capture_output=True, text=True)
    assert "voice coil (the tip's acceleration" in text.stdout
