"""The built-in textures: deterministic, physically sized, spanning the paper's range."""

from __future__ import annotations

import numpy as np
import pytest

from tactilize.features import extract_features
from tactilize.image import load_image
from tactilize.data import TEXTURE_DPI, builtin_map, builtin_textures, get_texture, png_bytes, texture_ids


@pytest.fixture(scope="module")
def feats():
    return {t.id: extract_features(t.image) for t in builtin_textures()}


def test_at_least_six_with_unique_ids():
    ids = texture_ids()
    assert len(ids) >= 6 and len(set(ids)) == len(ids)
    assert get_texture("corduroy").name == "Corduroy"
    with pytest.raises(KeyError):
        get_texture("velvet")


def test_deterministic():
    t = get_texture("sandpaper")
    fresh = type(t)(t.id, t.name, t.description, t.make, t.seed)
    assert np.array_equal(fresh.pixels_u8, t.pixels_u8)
    assert fresh.png == t.png


def test_physical_size_and_png_roundtrip():
    for t in builtin_textures():
        img = load_image(t.png)
        assert img.dpi[0] == pytest.approx(TEXTURE_DPI, rel=1e-3)
        assert img.width_m == pytest.approx(t.width_m, rel=1e-3)
        assert np.array_equal(np.round(img.pixels * 255).astype(np.uint8), t.pixels_u8)
        assert 0.03 < t.width_m < 0.2 and 0.03 < t.height_m < 0.2
        d = t.describe()
        assert d["width_mm"] == pytest.approx(t.width_m * 1e3)


def test_spans_fine_to_coarse(feats):
    fs = {k: f.spatial_frequency_per_m for k, f in feats.items()}
    # the paper's images run from 265 to 4217 cycles/m
    assert min(fs.values()) < 350
    assert max(v for k, v in fs.items() if k != "sandpaper") > 3500
    assert fs["corduroy"] == pytest.approx(1 / 3.6e-3, rel=0.02)
    assert fs["linen"] == pytest.approx(800, rel=0.02)


def test_spans_strong_to_weak_periodicity(feats):
    per = {k: f.periodicity for k, f in feats.items()}
    assert per["corduroy"] > 0.8 and per["linen"] > 0.8
    assert per["sandpaper"] < 0.05 and per["wood"] < 0.2


def test_oriented_and_isotropic(feats):
    assert feats["corduroy"].anisotropy > 0.9 and feats["linen"].anisotropy > 0.9
    assert feats["linen"].orientation_deg == pytest.approx(45.0, abs=1.0)
    assert feats["wood"].anisotropy > 0.5
    assert feats["dots"].anisotropy < 0.1 and feats["sandpaper"].anisotropy < 0.1


def test_patchwork_changes_across_the_picture():
    m = builtin_map("patchwork")
    f = m.field("spatial_frequency_per_m")
    rows, cols = f.shape
    top_left, top_right = f[0, 0], f[0, cols - 1]
    assert top_left == pytest.approx(1 / 3.0e-3, rel=0.05)
    assert top_right == pytest.approx(1 / 0.5e-3, rel=0.05)
    # Uniform textures stay uniform across their tiles.
    c = builtin_map("corduroy").field("spatial_frequency_per_m")
    assert c.max() / c.min() < 1.02


def test_png_bytes_carries_dpi():
    png = png_bytes(np.full((8, 10), 128, np.uint8), 150.0)
    img = load_image(png)
    assert img.shape == (8, 10) and img.dpi[0] == pytest.approx(150.0, rel=1e-3)
