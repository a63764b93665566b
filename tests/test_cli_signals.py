"""CLI: simulate, envelope and export print parseable JSON, write files, fail in one line."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import wave

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from tactilize.actuators.sma import WireSpec
from tactilize.cli import main

SPEC = WireSpec.preset("75um")


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


@pytest.fixture(scope="module")
def grating_png(tmp_path_factory):
    """A vertical-bar grating of 1000 cycles/m at 300 DPI, drawn here."""
    dpi = 300
    pitch_m = 0.0254 / dpi
    x = np.arange(240) * pitch_m
    row = 0.5 + 0.45 * np.cos(2 * math.pi * 1000.0 * x)
    img = np.tile(row, (180, 1))
    path = tmp_path_factory.mktemp("img") / "bars.png"
    Image.fromarray(np.round(img * 255).astype(np.uint8)).save(path, dpi=(dpi, dpi))
    return path


def test_simulate_a_stroke_reports_what_the_finger_gets():
    res = run("simulate", "--texture", "corduroy", "--speed", "40", "--json", "--profile", "paper")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["follows"] is True and doc["standby"] is True
    assert doc["displacement_pp_um"] >= 0.5
    assert 0 < doc["first_follow_ms"] <= 25
    assert doc["pulse_frequency_hz"] == pytest.approx(198.2, abs=0.5)  # the paper's law
    assert 400 < doc["current_ma"] < 600 and 0 < doc["pulse_width_ms"] < 1
    assert doc["peak_temperature_c"] <= SPEC.max_temperature_c
    cold = json.loads(run("simulate", "--texture", "corduroy", "--speed", "40", "--no-standby", "--json").output)
    assert cold["standby"] is False and cold["first_follow_ms"] > doc["first_follow_ms"]


def test_simulate_raw_drive_balances_its_energy():
    res = run("simulate", "--frequency", "50", "--pulse-width-ms", "0.5", "--current-ma", "500", "--duration", "3", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    for key in ("displacement_pp_um", "follows", "mean_temperature_c", "peak_temperature_c", "allowed"):
        assert key in doc
    assert doc["allowed"] is True and doc["duty_ratio"] == pytest.approx(0.025)
    # energy accounts balance (first law)
    total = doc["stored_j"] + doc["convected_j"] + doc["latent_j"]
    assert doc["electrical_j"] == pytest.approx(total, rel=1e-6)


def test_simulate_high_duty_is_neither_following_nor_allowed():
    res = run("simulate", "--frequency", "50", "--pulse-width-ms", "3", "--current-ma", "500", "--duration", "4", "--json")
    doc = json.loads(res.output)
    assert doc["follows"] is False and doc["allowed"] is False
    assert doc["mean_temperature_c"] > SPEC.austenite_finish_c


def test_simulate_text_and_plot(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "sim.png"
    res = run("simulate", "--frequency", "100", "--pulse-width-ms", "0.5", "--current-ma", "500", "--duration", "2", "--plot", str(out))
    assert res.exit_code == 0, res.output
    assert "follows" in res.output and "peak temperature" in res.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_envelope_json_and_plot(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "env.png"
    res = run("envelope", "--json", "--plot", str(out))
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    f = doc["frequencies_hz"]
    assert len(doc["max_width_s"]) == len(f) == len(doc["bands"])
    assert doc["wire"]["diameter_m"] == 75e-6 and doc["circuit"]["name"] == "aa-resistor"
    for band in doc["bands"]:
        lo, hi = band["felt_band_j"]
        assert 0 < lo <= hi <= band["max_pulse_energy_j"]
    direct = json.loads(run("envelope", "--circuit", "aa-direct", "--json").output)
    assert direct["circuit"]["current_relaxed_a"] > 2.3
    assert all(d < a for d, a in zip(direct["max_width_s"], doc["max_width_s"]))
    assert out.exists()


@pytest.mark.parametrize("fmt", ["wav", "csv", "json", "log", "ahap", "android", "hjif", "haptic"])
def test_export_each_format(grating_png, tmp_path, fmt):
    out = tmp_path / f"out.{fmt}"
    res = run("export", str(grating_png), "--speed", "60", "--format", fmt, "--duration", "0.5", "-o", str(out), "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["path"] == str(out) and doc["format"] == fmt
    assert doc["spatial_frequency_per_m"] == pytest.approx(1000, rel=0.02)
    if fmt == "wav":
        with wave.open(str(out)) as w:
            assert w.getframerate() == 48_000 and w.getnframes() == 24_000 and w.getnchannels() == 2
    elif fmt == "csv":
        assert out.read_text().splitlines()[0] == "time_s,channel_0,channel_1"
    elif fmt == "log":
        assert out.read_text().splitlines()[0].startswith("t_s,speed_m_s,x_m,y_m,ch0_pulse_frequency_hz")
    elif fmt == "json":
        saved = json.loads(out.read_text())
        # a synthetic stroke is a stroke: the drive log, its first row the drive at t = 0
        assert saved["rows"][0]["ch0_pulse_frequency_hz"] == pytest.approx(doc["pulse_frequency_hz"])
        assert saved["rows"][0]["speed_m_s"] == pytest.approx(0.060, rel=0.05)
    elif fmt == "hjif":
        saved = json.loads(out.read_text())
        assert saved["timescale"] == 1000 and len(saved["perceptions"][0]["channels"]) == 2
    elif fmt == "haptic":
        saved = json.loads(out.read_text())
        assert saved["signals"]["continuous"]["envelopes"]["frequency"]
    elif fmt == "ahap":
        saved = json.loads(out.read_text())
        assert "Version" in saved and "Pattern" in saved
    else:
        saved = json.loads(out.read_text())
        assert sum(saved["timings_ms"]) == 500


@pytest.mark.parametrize(
    "args",
    [
        ["simulate", "--frequency", "-5", "--pulse-width-ms", "1", "--current-ma", "500"],
        ["simulate", "--frequency", "50", "--pulse-width-ms", "30", "--current-ma", "500"],
        ["simulate", "--frequency", "50", "--pulse-width-ms", "1", "--current-ma", "nan"],
        ["simulate", "--frequency", "50", "--pulse-width-ms", "1", "--current-ma", "500", "--wire", "33um"],
        ["envelope", "--wire", "1mm"],
        ["envelope", "--circuit", "nine-volt"],
        ["simulate", "--texture", "corduroy"],
        ["simulate", "--texture", "nosuch", "--speed", "40"],
        ["simulate", "--texture", "corduroy", "--image", "IMAGE", "--speed", "40"],
        ["simulate", "--texture", "corduroy", "--speed", "nan"],
        ["simulate", "--texture", "corduroy", "--speed", "40", "--circuit", "nine-volt"],
        ["simulate"],
        ["export", "IMAGE", "--speed", "60", "--format", "mp3", "-o", "OUT"],
        ["export", "/nonexistent/x.png", "--speed", "60", "--format", "wav", "-o", "OUT"],
        ["export", "IMAGE", "--speed", "60", "--format", "wav", "-o", "/nonexistent/dir/x.wav"],
    ],
)
def test_bad_input_is_one_line_and_exit_2(args, grating_png, tmp_path):
    args = [str(grating_png) if a == "IMAGE" else str(tmp_path / "o") if a == "OUT" else a for a in args]
    proc = subprocess.run([sys.executable, "-m", "tactilize.cli", *args], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("tactilize: ") and "Traceback" not in proc.stderr
    assert proc.stdout == ""
