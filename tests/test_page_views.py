"""The page's figures in-process: Fig. 5 (spectrum view, page route and CLI), Fig. 16 (composite surface), repeat."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from fastapi.testclient import TestClient

from tactilize.maps.composite import CompositeMap
from tactilize.data import builtin_map, png_bytes
from tactilize.features import extract_features
from tactilize.image import load_image
from tactilize.maps.spectrumview import log_spectrum, peak_position_px, spectrum_view
from tactilize.maps.texturemap import texture_map
from tactilize.web import create_app
from tactilize.web.rows import DEFAULT_M_PER_CSS_PX

from test_web import FakeOutput, recv_type, stroke_rows

MM_PER_PX = DEFAULT_M_PER_CSS_PX * 1e3


def grating_png(period_px: float, angle_deg: float = 0.0, shape=(300, 400)) -> bytes:
    """A cosine grating of known period [px] as an 8-bit PNG at 96 dpi."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w]
    a = np.deg2rad(angle_deg)
    u = xx * np.cos(a) - yy * np.sin(a)
    return png_bytes((127 + 100 * np.cos(2 * np.pi * u / period_px)).astype(np.uint8), 96.0)


@pytest.fixture(scope="module")
def client():
    with TestClient(create_app(FakeOutput(), "paper", output_name="fake"), base_url="http://127.0.0.1") as c:
        yield c


# ------------------------------------------------------------------- Fig. 5


def test_log_spectrum_has_dc_in_the_centre_and_the_peak_where_marked():
    png = grating_png(10.0)
    img = load_image(png, width_mm=100.0)
    spec = log_spectrum(img.pixels)
    h, w = spec.shape
    assert spec[h // 2, w // 2] == spec.max()  # DC
    feat = extract_features(img)
    col, row = peak_position_px(feat.wave_vector_per_px, (h, w))
    # 400 px / 10 px = 40 cycles across: 40 bins right of DC, on DC's row.
    assert (round(col), round(row)) == (w // 2 + 40, h // 2)
    ac = spec.copy()
    ac[h // 2, w // 2] = 0
    assert np.unravel_index(np.argmax(ac), ac.shape) in {(h // 2, w // 2 + 40), (h // 2, w // 2 - 40)}


@pytest.mark.parametrize("period_px, angle_deg", [(10.0, 0.0), (16.0, 30.0), (8.0, 90.0)])
def test_spectrum_route_marks_the_peak_extract_features_finds(client, period_px, angle_deg):
    png = grating_png(period_px, angle_deg)
    r = client.post("/api/textures", files={"file": ("g.png", png, "image/png")}, data={"width_mm": "100"})
    assert r.status_code in (200, 201), r.text
    doc = client.get(f"/api/textures/{r.json()['id']}/spectrum").json()
    feat = extract_features(load_image(png, width_mm=100.0))
    # 400 px over 100 mm: a period of p px is p / 4 mm.
    assert feat.spatial_frequency_per_m * 1e-3 == pytest.approx(4.0 / period_px, rel=0.02)
    assert doc["peak"] and doc["spatial_frequency_per_mm"] == pytest.approx(feat.spatial_frequency_per_m * 1e-3, rel=1e-6)
    assert doc["spectral_intensity"] == pytest.approx(feat.spectral_intensity, rel=1e-6)
    # The marked position is that wave vector, in bins from DC.
    ch, cw = doc["crop"]
    dx = (doc["peak_px"][0] - cw // 2) * doc["bin_per_mm"][0]
    dy = (ch // 2 - doc["peak_px"][1]) * doc["bin_per_mm"][1]
    assert np.hypot(dx, dy) == pytest.approx(doc["spatial_frequency_per_mm"], rel=1e-6)
    assert doc["mirror_px"] == [pytest.approx(2 * (cw // 2) - doc["peak_px"][0]), pytest.approx(2 * (ch // 2) - doc["peak_px"][1])]
    assert doc["spectrum_url"].startswith("data:image/png;base64,")
    assert doc["tiles"]["rows"] >= 1 and len(doc["tiles"]["spatial_frequency_per_mm"][0]) == doc["tiles"]["cols"]


def test_spectrum_view_of_a_picture_that_changes_reports_its_tiles():
    tmap = builtin_map("patchwork")
    from tactilize.data import get_texture

    img = get_texture("patchwork").image
    view = spectrum_view(img.pixels, tmap.whole, tmap)
    f = np.array(view["tiles"]["spatial_frequency_per_mm"])
    assert f.max() > 1.5 * f.min()  # the quadrants differ


def test_cli_analyze_plot_draws_fig5(tmp_path):
    from tactilize.cli import main

    src = tmp_path / "grating.png"
    src.write_bytes(grating_png(10.0))
    out = tmp_path / "fig5.png"
    res = CliRunner().invoke(main, ["analyze", str(src), "--width-mm", "100", "--plot", str(out)])
    assert res.exit_code == 0, res.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "0.4" in res.output or "400.0" in res.output  # f_s 400 cycles/m printed as usual
    # Several pictures: one figure each, named after the picture (two of one stem are numbered).
    two = CliRunner().invoke(main, ["analyze", str(src), str(src), "--width-mm", "100", "--plot", str(out)])
    assert two.exit_code == 0, two.output
    for name in ("fig5-grating-1.png", "fig5-grating-2.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name


def test_cli_analyze_plot_marks_the_same_peak(tmp_path):
    from tactilize.cli.plots import plot_spectrum

    img = load_image(grating_png(16.0, 30.0), width_mm=100.0)
    feat = extract_features(img)
    view = plot_spectrum(img, feat, texture_map(img), str(tmp_path / "f.png"))
    assert view["spatial_frequency_per_mm"] == pytest.approx(feat.spatial_frequency_per_m * 1e-3)


# ------------------------------------------------------------------- Fig. 16


def test_composite_map_looks_up_the_picture_under_the_point():
    ids = ["corduroy", "linen", "canvas", "dots", "wood", "sandpaper"]
    maps = [builtin_map(i) for i in ids]
    c = CompositeMap.of(maps, 3)
    w, h = c.cell_m
    assert c.width_m == pytest.approx(3 * w) and c.height_m == pytest.approx(2 * h)
    for i, m in enumerate(maps):
        x0, y0 = c.origin_m(i)
        assert c.lookup(x0 + w / 2, y0 + h / 2) is m.lookup(w / 2, h / 2)
    assert c.lookup(-1e-6, 0.0) is None and c.lookup(3 * w, 0.0) is None and c.lookup(0.0, 2 * h) is None
    with pytest.raises(ValueError):
        CompositeMap.of([], 3)


def test_ws_composite_stroke_changes_the_spatial_frequency_at_the_boundary(client):
    ids = ["corduroy", "linen", "canvas", "dots", "wood", "sandpaper"]
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        ws.send_text(json.dumps({"type": "hello", "mm_per_px": MM_PER_PX}))
        recv_type(ws, "ready")
        ws.send_text(json.dumps({"type": "composite", "ids": ids, "cols": 3}))
        st = recv_type(ws, "state")
        assert st["texture"] is None and st["composite"]["ids"] == ids and st["composite"]["cols"] == 3
        cell_px = st["composite"]["cell_mm"][0] / MM_PER_PX
        seen = []
        # 20 mm/s from 40 px left of the boundary to 40 px right of it, in batches.
        t, x = 1000.0, cell_px - 40.0
        seq = 0
        while x < cell_px + 40.0:
            rows = stroke_rows(20.0, n=5, x0=x, t0=t)
            ws.send_text(json.dumps({"type": "samples", "batch": str(seq), "samples": rows}))
            d = recv_type(ws, "drive")
            seen.append((rows[-1][1] / MM_PER_PX, d["spatial_frequency_per_m"], d["on"]))
            t, x, seq = rows[-1][0] + 5.0, (rows[-1][1] + rows[1][1] - rows[0][1]) / MM_PER_PX, seq + 1
        # The tracker's position lags the newest sample by a little: leave 3 px either side.
        left = [f for xx, f, on in seen if xx < cell_px - 3 and on]
        right = [f for xx, f, on in seen if xx > cell_px + 3 and on]
        assert len(left) >= 3 and len(right) >= 3
        f_cord = builtin_map("corduroy").whole.spatial_frequency_per_m
        f_linen = builtin_map("linen").whole.spatial_frequency_per_m
        assert f_linen > 2 * f_cord
        assert all(f == pytest.approx(f_cord, rel=0.05) for f in left)
        assert all(f == pytest.approx(f_linen, rel=0.05) for f in right)
        # Back to a single picture: the composite is gone.
        ws.send_text(json.dumps({"type": "texture", "id": "linen"}))
        st = recv_type(ws, "state")
        assert st["texture"] == "linen" and "composite" not in st


@pytest.mark.parametrize(
    "msg, err",
    [
        ({"type": "composite"}, "'ids'"),
        ({"type": "composite", "ids": []}, "'ids'"),
        ({"type": "composite", "ids": ["corduroy"] * 13}, "'ids'"),
        ({"type": "composite", "ids": ["velvet"]}, "no texture"),
        ({"type": "composite", "ids": ["linen"], "cols": 0}, "'cols'"),
        ({"type": "texture", "id": "linen", "repeat": [0, 2]}, "'repeat'"),
        ({"type": "texture", "id": "linen", "repeat": [9, 9]}, "'repeat'"),
        ({"type": "texture", "id": "linen", "repeat": "2x2"}, "'repeat'"),
    ],
)
def test_ws_composite_and_repeat_refusals(client, msg, err):
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        ws.send_text(json.dumps(msg))
        assert err in recv_type(ws, "error")["message"]


def test_ws_repeated_picture_is_driven_beyond_the_first_copy(client):
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        ws.send_text(json.dumps({"type": "hello", "texture": "corduroy", "mm_per_px": MM_PER_PX}))
        recv_type(ws, "ready")
        ws.send_text(json.dumps({"type": "texture", "id": "corduroy", "repeat": [2, 1]}))
        st = recv_type(ws, "state")
        assert st["texture"] == "corduroy" and st["repeat"] == [2, 1]
        w_px = st["texture_width_mm"] / MM_PER_PX
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0, x0=w_px + 20)}))
        d = recv_type(ws, "drive")
        assert d["on"] and d["inside"]
        ws.send_text(json.dumps({"type": "samples", "samples": stroke_rows(20.0, x0=2 * w_px + 20, t0=2000.0)}))
        assert not recv_type(ws, "drive")["inside"]
