"""Profiles whose laws fail on their own domain, or whose band no output can
render, are refused when they load, with one clear line (not at every drive)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from tactilize.errors import ProfileError
from tactilize.mapping.profile import MAX_PROFILE_FREQUENCY_HZ, Profile, preset_names

BASE = """
[frequency]
{frequency}
[speed]
{speed}
[width]
{width}
{extra}
"""
GOOD = {"frequency": 'law = "log"\nk2 = 40.0', "speed": 'law = "constant"', "width": 'law = "constant"', "extra": ""}
BAD = {
    "division by zero": {"frequency": 'law = "power"\nreference_per_m = 0.0'},
    "speed reference zero": {"speed": 'law = "power"\nreference_mm_s = 0.0'},
    "negative power of zero speed": {"speed": 'law = "power"\nexponent = -1.0'},
    "overflow": {"frequency": 'law = "power"\nexponent = 1000.0'},
    "infinite width": {"width": 'law = "linear"\nk3 = 40.0\nunit_s = 1e308'},
    "half a megahertz": {"extra": '[actuator]\nmax_frequency_hz = 600000.0'},
}


def _toml(**changes: str) -> str:
    return BASE.format(**{**GOOD, **changes})


def test_every_preset_loads():
    for name in preset_names():
        Profile.preset(name)
    Profile.from_toml(_toml())


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_profile_that_cannot_drive_is_refused_at_load(case):
    with pytest.raises(ProfileError) as info:
        Profile.from_toml(_toml(**BAD[case]), source="bad.toml")
    assert info.value.source == "bad.toml"
    assert "\n" not in str(info.value)


def test_the_band_limit_is_what_outputs_render():
    Profile.from_toml(_toml(extra=f"[actuator]\nmax_frequency_hz = {MAX_PROFILE_FREQUENCY_HZ}"))
    with pytest.raises(ProfileError, match="max_frequency_hz"):
        Profile.from_toml(_toml(extra=f"[actuator]\nmax_frequency_hz = {MAX_PROFILE_FREQUENCY_HZ * 1.01}"))


@pytest.mark.parametrize("case", ["division by zero", "half a megahertz"])
def test_the_cli_says_so_in_one_line_and_exits_2(tmp_path, case):
    png = tmp_path / "g.png"
    x = np.arange(64)
    Image.fromarray((127 + 120 * np.sin(2 * np.pi * x / 8)[None, :] * np.ones((64, 1))).astype(np.uint8)).save(png)
    bad = tmp_path / "bad.toml"
    bad.write_text(_toml(**BAD[case]))
    proc = subprocess.run([sys.executable, "-m", "tactilize.cli", "drive", str(png), "--speed", "50", "--profile",
                           str(bad)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "bad.toml" in lines[0], proc.stderr


SURFACE = """rendering = "surface"
[surface]
tip_radius_mm = {tip}
[frequency]
law = "linear"
k1 = 1.0
[speed]
law = "proportional"
gain_per_m_s = 1.0
[width]
law = "linear"
k3 = 40.0
"""

# Every number of the paper preset negated: each law then gives nothing but zero or
# negative values, which the drive turns off, so the profile could never drive.
NEGATIVE = """
[frequency]
law = "log"
k2 = -40.0
[speed]
law = "sigmoid"
slope_per_mm_s = -0.05
centre_mm_s = -60.0
range = -2.9
floor = -0.1
[width]
law = "linear"
k3 = -40.0
l = -1.0
unit_s = -1e-5
[amplitude]
law = "constant"
value = -1.0
"""

OUT_OF_DOMAIN = {
    "a tip of 1e-300 mm": SURFACE.format(tip="1e-300"),
    "a tip of 11 mm": SURFACE.format(tip="11.0"),
    "a negative log coefficient": _toml(frequency='law = "log"\nk2 = -40.0'),
    "a negative width unit": _toml(width='law = "linear"\nk3 = 40.0\nunit_s = -1e-5'),
    "a width nowhere positive": _toml(width='law = "linear"\nk3 = -40.0\nl = 0.0'),
    "a speed law nowhere positive": _toml(speed='law = "sigmoid"\nrange = 0.0\nfloor = 0.0'),
    "a negative amplitude": _toml(extra='[amplitude]\nlaw = "constant"\nvalue = -1.0'),
    "pressure amplitude above 1": _toml(extra='[amplitude]\nlaw = "pressure"\nmaximum = 2.0'),
    "anisotropy threshold below 0": _toml(extra='[direction]\nlaw = "project"\nmin_anisotropy = -0.2'),
    "every number negative": NEGATIVE,
}


@pytest.mark.parametrize("case", sorted(OUT_OF_DOMAIN))
def test_a_number_outside_its_domain_is_refused_at_load(case):
    with pytest.raises(ProfileError) as info:
        Profile.from_toml(OUT_OF_DOMAIN[case], source="bad.toml")
    assert info.value.source == "bad.toml" and "\n" not in str(info.value)


def test_the_ends_of_the_tip_radius_range_render_a_stroke():
    from tactilize.data import builtin_map, get_texture
    from tactilize.export import parse_stroke, run_stroke
    from tactilize.mapping.profile import TIP_RADIUS_RANGE_M
    from tactilize.surface.model import surface_model

    tmap = builtin_map("corduroy")
    stroke = parse_stroke([[i / 200, 5 + 20 * i / 200, 10, 0.5] for i in range(200)], "<stroke>", tmap.width_m,
                          tmap.height_m)
    for tip_m in TIP_RADIUS_RANGE_M:
        p = Profile.from_toml(SURFACE.format(tip=tip_m * 1e3))
        assert p.tip_radius_m == pytest.approx(tip_m)
        surface = surface_model(get_texture("corduroy").image, tip_radius_m=p.tip_radius_m)
        assert run_stroke(stroke, tmap, p, surface=surface).events is not None


@pytest.mark.parametrize(
    "command",
    [
        ["simulate", "--texture", "corduroy", "--speed", "50", "--duration", "0.2"],
        ["profile", "report", "--no-wire"],
        ["serve", "--no-open", "--port", "0"],
    ],
    ids=["simulate", "profile report", "serve"],
)
@pytest.mark.parametrize("case", ["a tip of 1e-300 mm", "every number negative"])
def test_commands_refuse_such_a_profile_in_one_line_with_exit_2(tmp_path, command, case):
    bad = tmp_path / "negative.toml"
    bad.write_text(OUT_OF_DOMAIN[case])
    proc = subprocess.run([sys.executable, "-m", "tactilize.cli", *command, "--profile", str(bad)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "negative.toml" in lines[0] and "internal error" not in lines[0], proc.stderr


def test_simulate_reports_a_drive_that_is_off():
    """A pen at rest on the surface rendering drives nothing: the report says so, it does not fail."""
    proc = subprocess.run([sys.executable, "-m", "tactilize.cli", "simulate", "--texture", "sandpaper", "--speed", "0",
                           "--duration", "0.2", "--profile", "surface"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "strength none (off)" in proc.stdout
