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
