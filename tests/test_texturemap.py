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


def _noisy_grating(period_px: float, angle_deg: float, shape=(768, 1024)) -> tz.TextureImage:
    # 96 dpi: frequency_per_m = 1 / (period_px * pitch)
    pitch = 0.0254 / 96
    arr = grating_array(shape, 1.0 / (period_px * pitch), angle_deg, 96, contrast=0.6, noise=0.08, seed=3)
    return tz.load_image(arr, dpi=96)


@pytest.mark.parametrize(("period_px", "angle_deg"), [(4.5, 0.0), (9.0, 33.0), (16.0, 120.0), (30.0, 61.0)])
def test_sampled_tiles_agree_with_whole_tiles(period_px, angle_deg):
    img = _noisy_grating(period_px, angle_deg)
    whole_tiles = tz.texture_map(img)
    sampled = tz.texture_map(img, sample_px=whole_tiles.tile_px // 2)
    assert (whole_tiles.tile_px, sampled.sample_px, whole_tiles.sample_px) == (128, 64, None)
    assert sampled.grid == whole_tiles.grid
    f_full, f_half = whole_tiles.field("spatial_frequency_per_m"), sampled.field("spatial_frequency_per_m")
    truth = 1.0 / (period_px * img.pitch_m[0])
    # every local frequency right to 1 % either way (two periods or more in the sample)
    assert np.abs(f_half / truth - 1).max() < 0.01
    assert np.abs(f_full / truth - 1).max() < 0.01
    # i_s is given for the tile's size: the same texture reads the same
    i_full, i_half = whole_tiles.field("spectral_intensity"), sampled.field("spectral_intensity")
    assert np.abs(i_half - i_full).max() < 0.005
    assert sampled.summary()["sample_mm"] == pytest.approx(64 * img.pitch_m[0] * 1e3)
    assert whole_tiles.summary()["sample_mm"] == pytest.approx(128 * img.pitch_m[0] * 1e3)


def test_auto_sample_falls_back_to_whole_tiles():
    # 45 px periods: the 64 px half tile holds 1.4 of them, too few to measure well
    assert tz.texture_map(_noisy_grating(45.0, 10.0), sample_px="auto").sample_px is None
    assert tz.texture_map(_noisy_grating(12.0, 10.0), sample_px="auto").sample_px == 64
    # tiles of 32 px: a 16 px sample is too small whatever the texture
    small = _noisy_grating(4.0, 10.0, shape=(160, 200))
    tmap = tz.texture_map(small, sample_px="auto")
    assert tmap.tile_px == 32 and tmap.sample_px is None
    # a flat picture has no period to judge by
    flat = tz.load_image(np.full((768, 1024), 0.4, np.float32), dpi=96)
    assert tz.texture_map(flat, sample_px="auto").sample_px is None


@pytest.mark.parametrize("bad", [3, 129, "half"])
def test_sample_px_out_of_range_is_refused(bad):
    with pytest.raises(ValueError, match="sample_px"):
        tz.texture_map(_noisy_grating(12.0, 0.0, shape=(256, 256)), tile_px=128, sample_px=bad)


def test_maps_are_feature_lookups_and_the_package_loads_lazily():
    import subprocess
    import sys

    from tactilize.maps import CompositeMap, FeatureLookup

    tmap = tz.texture_map(tz.load_image(_two_halves(), dpi=DPI), tile_px=64)
    both = CompositeMap.of([tmap, tmap], cols=2)
    assert isinstance(tmap, FeatureLookup) and isinstance(both, FeatureLookup)
    assert not isinstance(object(), FeatureLookup)
    assert both.lookup(tmap.width_m * 1.5, tmap.height_m * 0.25) == tmap.lookup(tmap.width_m * 0.5, tmap.height_m * 0.25)
    # The protocol and a composite alone do not load the FFT stack a map needs.
    code = "import sys, tactilize.maps.lookup, tactilize.maps.composite; print('scipy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
