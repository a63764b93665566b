"""``tactilize site``: the model file, the built folder, its weights and the CLI's answers to bad input."""

from __future__ import annotations

import gzip
import json

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from tactilize.cli import main
from tactilize.site import MAX_MODEL_BYTES, build_site, decode_model, encode_model, model_bytes, rule_parameters
from tactilize.site.builder import static_files
from tactilize.surface import events, stroke
from tactilize.surface.model import surface_model


def _photo(path, size=(2000, 1500), seed=0, period=41):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0 : size[1], 0 : size[0]]
    g = 0.5 + 0.25 * np.sin(2 * np.pi * x / period) * np.sin(2 * np.pi * y / 53) + 0.05 * rng.standard_normal(x.shape)
    Image.fromarray((np.clip(g, 0, 1) * 255).astype(np.uint8)).save(path, quality=90)


def test_model_file_round_trip_keeps_heights_within_one_level():
    rng = np.random.default_rng(1)
    s = surface_model(rng.random((60, 80)).astype(np.float32), pitch_m=1e-4)
    m = decode_model(encode_model(s, material="wool", product_id="a/b"))
    assert m.header["material"] == "wool" and m.header["id"] == "a/b"
    assert m.levels.shape == (60, 80)
    assert np.abs(m.heights - s.height).max() <= m.header["scale"] * 0.5 + 1e-6
    back = m.surface()
    assert back.prominence_floor == s.prominence_floor and back.tip_radius_m == s.tip_radius_m
    assert back.display_pitch_m == s.display_pitch_m and back.surface_pitch_m == s.surface_pitch_m


def test_rule_parameters_are_the_python_renderers():
    r = rule_parameters()
    assert r["lookahead_s"] == stroke.LOOKAHEAD_S and r["late_s"] == stroke.LATE_S
    assert r["min_interval_s"] == events.MIN_INTERVAL_S and r["rate_only_hz"] == events.RATE_ONLY_HZ
    assert r["tracker"]["window_s"] == 0.030 and r["tracker"]["max_samples"] == 64


@pytest.mark.parametrize("seed", [0, 1])
def test_a_2000_px_photo_makes_a_model_of_at_most_64_kb(seed):
    rng = np.random.default_rng(seed)
    noise = rng.random((1500, 2000)).astype(np.float32)  # the worst case: nothing to compress
    data = model_bytes(noise, (0.0254 / 96, 0.0254 / 96))
    assert len(data) <= MAX_MODEL_BYTES == 64 * 1024
    assert max(decode_model(data).levels.shape) >= 200


def test_element_and_its_imports_weigh_at_most_30_kb_gzipped():
    total = sum(len(gzip.compress(f.read_bytes(), 9)) for f in static_files() if f.suffix == ".js")
    assert total <= 30 * 1024, total


def test_build_from_a_manifest_passes_material_through(tmp_path):
    (tmp_path / "ph").mkdir()
    _photo(tmp_path / "ph" / "a.jpg")
    _photo(tmp_path / "ph" / "b.jpg", size=(300, 200), seed=2)
    (tmp_path / "ph" / "bad.jpg").write_bytes(b"not an image")
    (tmp_path / "m.jsonl").write_text('{"id": "shirt/1", "path": "ph/a.jpg", "material": "linen", "width_mm": 300}\n'
                                      '{"id": "b", "path": "ph/b.jpg"}\n{"id": "bad", "path": "ph/bad.jpg"}\n')
    s = build_site(str(tmp_path / "m.jsonl"), tmp_path / "out")
    assert [p["id"] for p in s.products] == ["b", "shirt/1"]
    assert [f[0] for f in s.failed] == ["bad"]
    out = tmp_path / "out"
    for name in ("index.html", "tactile-surface.js", "surface-rule.js", "vibrate.js", "pen-input.js", "pulse-worklet.js",
                 "shop.css", "products.json"):
        assert (out / name).is_file(), name
    shirt = next(p for p in s.products if p["id"] == "shirt/1")
    m = decode_model((out / "models" / f"{shirt['slug']}.tsf").read_bytes())
    assert m.header["material"] == "linen" and m.header["id"] == "shirt/1"
    assert abs(m.header["cols"] * m.header["display_pitch_m"][0] - 0.300) < 1e-9  # the real width kept
    assert shirt["model_bytes"] <= MAX_MODEL_BYTES
    assert decode_model((out / "models" / f"{s.products[0]['slug']}.tsf").read_bytes()).header["material"] is None
    page = (out / "p" / f"{shirt['slug']}.html").read_text()
    assert f'<tactile-surface model="../models/{shirt["slug"]}.tsf"' in page and "http" not in page
    assert json.loads((out / "products.json").read_text())[1]["material"] == "linen"


def test_cli_site_builds_and_bad_input_is_one_line_and_exit_2(tmp_path):
    (tmp_path / "ph").mkdir()
    _photo(tmp_path / "ph" / "a.png", size=(200, 150))
    r = CliRunner().invoke(main, ["site", str(tmp_path / "ph"), "-o", str(tmp_path / "out"), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["products"] == 1
    for args in (["site", str(tmp_path / "nothing"), "-o", str(tmp_path / "o2")],
                 ["site", str(tmp_path / "ph"), "-o", str(tmp_path / "ph" / "a.png")],
                 ["site", str(tmp_path / "ph"), "-o", str(tmp_path / "o3"), "--model-px", "3"],
                 ["site", str(tmp_path / "ph")]):
        r = CliRunner().invoke(main, args)
        assert r.exit_code == 2, (args, r.output)
        assert len(r.output.strip().splitlines()) == 1, r.output
        assert r.output.startswith("tactilize: ")


def test_serve_site_router_hands_out_the_built_files_only(tmp_path):
    from fastapi import FastAPI
    from fastapi.testclient import TestClient

    from tactilize.errors import CatalogError
    from tactilize.site.routes import site_router

    (tmp_path / "ph").mkdir()
    _photo(tmp_path / "ph" / "a.png", size=(200, 150))
    s = build_site(str(tmp_path / "ph"), tmp_path / "out")
    (tmp_path / "secret.txt").write_text("no")
    app = FastAPI()
    app.include_router(site_router(tmp_path / "out"))
    c = TestClient(app)
    assert "<tactile-surface" in c.get("/shop/").text
    js = c.get("/shop/tactile-surface.js")
    assert js.status_code == 200 and js.headers["content-type"].startswith("text/javascript")
    m = c.get(f"/shop/models/{s.products[0]['slug']}.tsf")
    assert m.status_code == 200 and m.content[:4] == b"TSF1"
    assert c.get("/shop/../secret.txt").status_code == 404
    assert c.get("/shop/%2e%2e/secret.txt").status_code == 404
    with pytest.raises(CatalogError):
        site_router(tmp_path / "ph")
