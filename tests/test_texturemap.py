"""texturemap.py: local features on tiles, O(1) lookup by physical position."""

from __future__ import annotations

import numpy as np
import pytest

import tactilize as tz
from conftest import grating_array

DPI = 254.0  # 0.1 mm pixels
PITCH = 0.0254 / DPI


def _two_halves() -> np.ndarray:
    left = grating_array((256, 256), 1200.0, 0.0, DPI)
    right = grating_array((256, 256), 400.0, 90.0, DPI)
    return np.concatenate([left, right], axis=1)


def test_lookup_returns_the_local_texture():
    tmap = tz.texture_map(tz.load_image(_two_halves(), dpi=DPI), tile_px=64)
    assert tmap.grid == (4, 8)
    left = tmap.lookup(5e-3, 12e-3)
    right = tmap.lookup(40e-3, 12e-3)
    assert left.spatial_frequency_per_m == pytest.approx(1200, rel=0.02)
    assert right.spatial_frequency_per_m == pytest.approx(400, rel=0.02)
    assert abs(right.orientation_deg - 90) < 2
    # the whole picture mixes both
    assert tmap.whole.periodicity < left.periodicity


def test_lookup_outside_is_none_and_edges_are_inside():
    tmap = tz.texture_map(tz.load_image(_two_halves(), dpi=DPI), tile_px=64)
    assert tmap.lookup(-1e-6, 0.01) is None
    assert tmap.lookup(0.01, tmap.height_m) is None
    assert tmap.lookup(tmap.width_m, 0.0) is None
    assert tmap.lookup(0.0, 0.0) is not None
    assert tmap.lookup(tmap.width_m - 1e-9, tmap.height_m - 1e-9) is tmap.tiles[-1][-1]


def test_ragged_edges_fall_into_the_last_tile():
    arr = grating_array((150, 200), 800.0, 30.0, DPI)
    tmap = tz.texture_map(tz.load_image(arr, dpi=DPI), tile_px=64)
    assert tmap.grid == (2, 3)
    assert tmap.lookup(tmap.width_m - 1e-6, tmap.height_m - 1e-6) is tmap.tiles[1][2]


def test_small_image_is_one_tile_and_uniform_maps_agree():
    arr = grating_array((40, 50), 800.0, 30.0, DPI)
    tmap = tz.texture_map(tz.load_image(arr, dpi=DPI), tile_px=64)
    assert tmap.grid == (1, 1)
    assert tmap.lookup(1e-3, 1e-3) == tmap.whole


def test_at_pitch_rescales_every_tile():
    tmap = tz.texture_map(tz.load_image(_two_halves(), dpi=DPI), tile_px=64)
    half = tmap.at_pitch(2 * PITCH)
    assert half.width_m == pytest.approx(2 * tmap.width_m)
    a = tmap.lookup(5e-3, 5e-3).spatial_frequency_per_m
    b = half.lookup(10e-3, 10e-3).spatial_frequency_per_m
    assert b == pytest.approx(a / 2, rel=1e-12)


def test_summary_reports_the_spread():
    s = tz.texture_map(tz.load_image(_two_halves(), dpi=DPI), tile_px=64).summary()
    assert s["spatial_frequency_per_m_min"] == pytest.approx(400, rel=0.03)
    assert s["spatial_frequency_per_m_max"] == pytest.approx(1200, rel=0.03)
    assert s["grid_rows"] == 4 and s["grid_cols"] == 8
