"""The CLI's analyze and drive commands: JSON that agrees with the library, one-line errors."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

import tactilize as tz
from conftest import grating_array
from tactilize.cli import main


@pytest.fixture
def grating_png(tmp_path):
    arr = grating_array((200, 260), 800.0, 35.0, 300)
    path = tmp_path / "grating.png"
    Image.fromarray((arr * 255).round().astype(np.uint8)).save(path, dpi=(300, 300))
    return path


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def test_analyze_json_agrees_with_the_library(grating_png):
    res = run("analyze", str(grating_png), "--json")
    assert res.exit_code == 0, res.output
    docs = json.loads(res.output)
    # Always a list, one object per image: one image too.
    assert isinstance(docs, list) and len(docs) == 1
    doc = docs[0]
    feat = tz.extract_features(tz.load_image(grating_png))
    assert doc["spatial_frequency_per_m"] == pytest.approx(feat.spatial_frequency_per_m, rel=1e-9)
    assert doc["spectral_intensity"] == pytest.approx(feat.spectral_intensity, rel=1e-9)
    assert doc["orientation_deg"] == pytest.approx(feat.orientation_deg, rel=1e-9)
    assert doc["spatial_frequency_per_m"] == pytest.approx(800, rel=0.01)


def test_analyze_several_images_gives_a_list_and_dpi_applies(grating_png, tmp_path):
    res = run("analyze", str(grating_png), str(grating_png), "--dpi", "150", "--json")
    docs = json.loads(res.output)
    assert isinstance(docs, list) and len(docs) == 2
    assert docs[0]["spatial_frequency_per_m"] == pytest.approx(400, rel=0.01)


def test_analyze_table_is_readable(grating_png):
    res = run("analyze", str(grating_png))
    assert res.exit_code == 0
    assert "spatial frequency" in res.output and "cycles/m" in res.output


def test_drive_json_agrees_with_the_library(grating_png):
    res = run("drive", str(grating_png), "--speed", "30", "--json", "--profile", "paper")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    feat = tz.extract_features(tz.load_image(grating_png))
    drv = tz.Profile.preset("paper").drive(feat, speed_m_s=0.030)
    assert doc["pulse_frequency_hz"] == pytest.approx(drv.pulse_frequency_hz)
    assert doc["pulse_width_ms"] == pytest.approx(drv.pulse_width_s * 1e3)
    assert doc["duty_ratio"] == pytest.approx(drv.duty_ratio)
    assert doc["amplitude"] == pytest.approx(drv.amplitude)
    assert doc["clamped"] == list(drv.clamped)


def test_drive_with_a_profile_file(grating_png, tmp_path):
    prof = tz.Profile.preset("paper").replace(name="slow", speed=tz.mapping.ConstantSpeed(0.5))
    path = prof.save(tmp_path / "slow.toml")
    doc = json.loads(run("drive", str(grating_png), "--speed", "50", "--profile", str(path), "--json").output)
    f_s = doc["spatial_frequency_per_m"]
    import math

    assert doc["pulse_frequency_hz"] == pytest.approx(0.5 * 40 * math.log(f_s + 1))


@pytest.mark.parametrize(
    "args, needle",
    [
        (["analyze", "{missing}"], "file not found"),
        (["analyze", "{text}"], "not an image"),
        (["analyze", "{png}", "--dpi", "0"], "positive"),
        (["analyze", "{png}", "--width-mm", "-2"], "positive"),
        (["drive", "{png}", "--speed", "-5"], "--speed"),
        (["drive", "{png}", "--speed", "10", "--profile", "nope"], "nope"),
        (["drive", "{cut}", "--speed", "10"], "cut.png"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(args, needle, grating_png, tmp_path):
    text = tmp_path / "notes.png"
    text.write_text("not an image at all")
    cut = tmp_path / "cut.png"
    cut.write_bytes(grating_png.read_bytes()[:300])
    subs = {"{missing}": str(tmp_path / "missing.png"), "{text}": str(text), "{png}": str(grating_png), "{cut}": str(cut)}
    argv = [subs.get(a, a) for a in args]
    proc = subprocess.run([sys.executable, "-m", "tactilize.cli", *argv], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert needle in lines[0]
    assert "Traceback" not in proc.stderr


def test_analyze_plot_draws_one_file_per_image(grating_png, tmp_path):
    other = tmp_path / "other.png"
    other.write_bytes(grating_png.read_bytes())
    res = run("analyze", str(grating_png), str(other), "--plot", str(tmp_path / "fig.png"), "--json")
    assert res.exit_code == 0, res.output
    docs = json.loads(res.output)
    assert [d["plot"] for d in docs] == [str(tmp_path / "fig-grating.png"), str(tmp_path / "fig-other.png")]
    for d in docs:
        with Image.open(d["plot"]) as im:
            assert im.size[0] > 500
    # One image: the file named, as before.
    res = run("analyze", str(grating_png), "--plot", str(tmp_path / "one.png"))
    assert res.exit_code == 0 and (tmp_path / "one.png").exists() and "wrote" in res.output


def test_simulate_a_stroke_refuses_a_plot_it_cannot_draw(grating_png, tmp_path):
    out = tmp_path / "stroke.png"
    res = CliRunner().invoke(main, ["simulate", "--image", str(grating_png), "--speed", "30", "--plot", str(out)])
    assert res.exit_code == 2
    assert res.output.strip().startswith("tactilize: --plot: draws the raw mode only")
    assert len(res.output.strip().splitlines()) == 1
    assert not out.exists()


def test_simulate_rounds_the_strength(grating_png):
    res = run("simulate", "--image", str(grating_png), "--speed", "30", "--duration", "0.3")
    assert res.exit_code == 0, res.output
    shown = re.search(r"strength (\S+)", res.output).group(1)
    assert re.fullmatch(r"\d\.\d\d", shown), shown
