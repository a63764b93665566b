"""`profile report --serial`: strokes played to the firmware on the virtual board, in simulated time."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from tactilize.features import extract_features
from tactilize.mapping import Profile
from tactilize.serial_report import board_stroke
from tactilize.surface import surface_model
from tactilize.surface.fields import bump_field

SURFACE = Profile.preset("surface")


def _bumps(spacing_m=2.5e-3, radius_m=0.6e-3):
    """Bumps in a row on the line a straight stroke through the picture's centre follows."""
    size = (40e-3, 10e-3)
    cx = np.arange(3e-3, size[0] - 2e-3, spacing_m)
    f = bump_field(np.stack([cx, np.full(cx.size, size[1] / 2)], 1), radius_m, size, 0.05e-3)
    return f, surface_model(f.heights, pitch_m=f.pitch_m)


def test_pulses_on_the_pin_come_at_the_crossings():
    """40 mm/s over bumps 2.5 mm apart: 16 crossings a second.  The pin's rate equals the true
    crossings' within 10 %, each pulse within 5 ms of a crossing (p95), and of its rendered event."""
    f, sm = _bumps()
    row = board_stroke(SURFACE, 0.04, surface=sm, bumps=f, duration_s=1.5)
    assert row["rendering"] == "surface" and row["crossings"] >= 20
    crossings_per_s = row["crossings"] / 1.5
    assert row["pulses_per_s"] == pytest.approx(crossings_per_s, rel=0.10)
    assert row["crossing_p95_ms"] <= 5.0
    assert row["event_p95_ms"] <= 1.0
    assert row["pulses"] == row["rendered"] == row["fired"] and row["skipped"] == row["late"] == 0


def test_the_report_is_repeatable():
    f, sm = _bumps()
    a = board_stroke(SURFACE, 0.06, surface=sm, bumps=f, duration_s=0.5)
    b = board_stroke(SURFACE, 0.06, surface=sm, bumps=f, duration_s=0.5)
    assert a == b


def test_the_boards_heat_estimate_skips_what_the_circuit_cannot_take():
    """A dense row of bumps fast on the hottest circuit (aa-direct): the board skips pulses and
    the pin shows exactly the others; on aa-resistor the same stroke loses none."""
    f, sm = _bumps(spacing_m=0.8e-3, radius_m=0.3e-3)
    hot = board_stroke(SURFACE, 0.16, surface=sm, circuit="aa-direct", duration_s=1.0)
    assert hot["skipped"] > 0
    assert hot["pulses"] == hot["rendered"] - hot["skipped"]
    cool = board_stroke(SURFACE, 0.16, surface=sm, circuit="aa-resistor", duration_s=1.0)
    assert cool["skipped"] == 0 and cool["pulses"] == cool["rendered"]


def test_a_steady_profile_reports_the_windowed_drive():
    """The paper's profile: its drive sent with SET; the pin's rate is the drive's frequency."""
    from tactilize.data import get_texture

    paper = Profile.preset("paper")
    img = get_texture("linen").image
    feat = extract_features(img)
    want = paper.drive(feat, 0.02).pulse_frequency_hz
    row = board_stroke(paper, 0.02, features=feat, duration_s=1.0)
    assert row["rendering"] == "steady" and row["frequency_hz"] == pytest.approx(want, rel=1e-3)
    assert abs(row["pulses_per_s"] - want) <= 1.5  # whole pulses in one second
    assert row["event_p95_ms"] is None


@pytest.fixture(scope="module")
def bumps_png(tmp_path_factory):
    f, _ = _bumps()
    p = tmp_path_factory.mktemp("serial") / "bumps.png"
    Image.fromarray(np.round(f.heights * 255).astype(np.uint8)).save(p)
    return p


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "tactilize.cli", "profile", "report", *map(str, args)],
                          capture_output=True, text=True)


def test_cli_reports_the_serial_link_per_texture_and_speed(bumps_png):
    r = _cli("--image", bumps_png, "--width-mm", 40, "--no-wire", "--serial", "--json")
    assert r.returncode == 0, r.stderr
    rows = json.loads(r.stdout)["serial"]
    assert [row["speed_mm_s"] for row in rows] == [10.0, 20.0, 40.0, 60.0, 100.0, 160.0]
    # Bumps 2.5 mm apart along the stroke: speed / spacing crossings a second reach the pin.
    for row in rows:
        assert row["texture"] == str(bumps_png) and row["skipped"] == 0
        assert row["pulses_per_s"] == pytest.approx(row["speed_mm_s"] / 2.5, rel=0.15)
    text = _cli("--image", bumps_png, "--width-mm", 40, "--no-wire", "--serial")
    assert text.returncode == 0 and "virtual board, simulated time" in text.stdout


def test_cli_refuses_an_unknown_circuit_in_one_line(bumps_png):
    r = _cli("--image", bumps_png, "--width-mm", 40, "--no-wire", "--serial", "--circuit", "nosuch")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().count("\n") == 0 and "--circuit nosuch" in r.stderr
