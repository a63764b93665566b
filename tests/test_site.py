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


@pytest.mark.parametrize("material", [None, "fabric-knit"])
def test_model_file_round_trip_keeps_heights_within_one_level(material):
    rng = np.random.default_rng(1)
    s = surface_model(rng.random((60, 80)).astype(np.float32), pitch_m=1e-4, material=material)
    m = decode_model(encode_model(s, product_id="a/b"))
    assert m.header["material"] == material and m.header["id"] == "a/b"
    assert m.levels.shape == (60, 80)
    assert np.abs(m.heights - s.height).max() <= m.header["scale"] * 0.5 * (1 + 1e-6)
    back = m.surface()
    assert back.prominence_floor == s.prominence_floor and back.tip_radius_m == s.tip_radius_m
    assert back.display_pitch_m == s.display_pitch_m and back.surface_pitch_m == s.surface_pitch_m
    # A material's surface comes back in metres, with its micro-roughness drawn as Python draws it.
    assert back.full_prominence == s.full_prominence and m.header["full_prominence"] == events.full_prominence(s)
    assert back.micro == s.micro and (material is None) == (back.micro is None)
    x, y = rng.uniform(0, 7e-3, 50), rng.uniform(0, 5e-3, 50)
    assert np.array_equal(back.micro_at(x, y), s.micro_at(x, y))


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
    (tmp_path / "m.jsonl").write_text('{"id": "shirt/1", "path": "ph/a.jpg", "material": "fabric-woven", "width_mm": 300}\n'
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
    assert m.header["material"] == "fabric-woven" and m.header["id"] == "shirt/1"
    assert abs(m.header["cols"] * m.header["display_pitch_m"][0] - 0.300) < 1e-9  # the real width kept
    assert shirt["model_bytes"] <= MAX_MODEL_BYTES
    assert decode_model((out / "models" / f"{s.products[0]['slug']}.tsf").read_bytes()).header["material"] is None
    page = (out / "p" / f"{shirt['slug']}.html").read_text()
    assert f'<tactile-surface model="../models/{shirt["slug"]}.tsf"' in page and "http" not in page
    assert json.loads((out / "products.json").read_text())[1]["material"] == "fabric-woven"


def test_build_from_a_manifest_renders_each_rows_relief(tmp_path):
    """A manifest's ``relief_mm`` (as ``--relief-mm``) sets the product's relief: the model's relief
    scale grows with it, linearly, and a row without one keeps its material's typical relief."""
    (tmp_path / "ph").mkdir()
    _photo(tmp_path / "ph" / "a.jpg", size=(600, 400))
    (tmp_path / "m.jsonl").write_text('{"id": "typical", "path": "ph/a.jpg", "material": "cork"}\n'
                                      '{"id": "given", "path": "ph/a.jpg", "material": "cork", "relief_mm": 0.05}\n'
                                      '{"id": "twice", "path": "ph/a.jpg", "material": "cork", "relief_mm": 0.1}\n')
    s = build_site(str(tmp_path / "m.jsonl"), tmp_path / "out")
    scale = {p["id"]: decode_model((tmp_path / "out" / "models" / f"{p['slug']}.tsf").read_bytes()).header["relief_scale_m"]
             for p in s.products}
    assert scale["given"] != scale["typical"]
    assert scale["twice"] == pytest.approx(2 * scale["given"], rel=1e-9)


def _events_along(model, speed_m_s=0.1):
    """A steady stroke across the middle of a model file's surface: the Python renderer's events."""
    from tactilize.pen.replay import replay_stroke
    from tactilize.pen.samples import PenSample

    surface = model.surface()
    t = np.arange(0.0, 0.6, 1 / 240)
    x, y = 0.1 * surface.width_m + speed_m_s * t, 0.5 * surface.height_m
    return replay_stroke(surface, [PenSample(float(a), float(b), y, None) for a, b in zip(t, x)])


def test_a_product_of_a_material_is_rendered_as_the_server_renders_that_material(tmp_path):
    """Three rows of one photo: the picture alone, brushed metal, granite.  Each model holds what
    ``--material`` renders for the photo (its relief scale, micro-roughness, full prominence in
    metres), and the three feel different."""
    from tactilize.image import load_image
    from tactilize.materials import MaterialChoice
    from tactilize.site import read_model

    _photo(tmp_path / "sheet.png", size=(800, 600))
    (tmp_path / "m.csv").write_text("id,path,width_mm,material\nalone,sheet.png,80,\nbrushed,sheet.png,80,metal-brushed\n"
                                    "granite,sheet.png,80,Stone-Granite\n")
    s = build_site(str(tmp_path / "m.csv"), tmp_path / "out")
    models = {p["id"]: read_model(tmp_path / "out" / "models" / f"{p['slug']}.tsf") for p in s.products}
    alone = models["alone"].header
    assert (alone["material"], alone["relief_scale_m"], alone["micro"]) == (None, None, None)
    assert alone["full_prominence"] == events.FULL_PROMINENCE
    img = load_image(tmp_path / "sheet.png", width_mm=80)
    for ident, name in (("brushed", "metal-brushed"), ("granite", "stone-granite")):
        server = surface_model(img, material=name)  # what analyze, export and serve render with --material
        h = models[ident].header
        assert h["material"] == name and h["rendered_as"] == MaterialChoice.of(name).label()
        assert h["relief_scale_m"] == server.relief.scale_m, "the relief scale is the whole picture's"
        assert h["micro"] == server.micro.to_dict() and h["full_prominence"] == server.full_prominence
        assert h["prominence_floor"] < 1e-3  # metres, not luminance units
    assert [p["material"] for p in s.products] == [None, "metal-brushed", "stone-granite"]
    felt = {ident: _events_along(m) for ident, m in models.items()}
    assert len(felt["granite"]) >= 5, felt
    # The same bumps, but brushed metal's relief is 0.6 um RMS and granite's hundreds of times
    # deeper: from the least felt prominence to the full one, granite's are far the stronger.
    strength = {k: float(np.mean([e.strength for e in v])) for k, v in felt.items()}
    assert strength["brushed"] + 0.3 < strength["granite"], strength
    same = [(round(a.t_s, 4), round(a.strength, 3)) for a in felt["granite"]]
    assert same != [(round(a.t_s, 4), round(a.strength, 3)) for a in felt["alone"]]


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


def test_pages_hold_the_first_models_and_preload_the_next(tmp_path):
    import base64
    import re

    for i in range(3):
        _photo(tmp_path / f"p{i}.png", size=(300, 200), seed=i)
    s = build_site(str(tmp_path / "p*.png"), tmp_path / "site")
    held = lambda page: re.findall(r'<script type="application/octet-stream">([^<]+)</script>', page)
    index = (tmp_path / "site" / "index.html").read_text()
    first, second = s.products[0]["slug"], s.products[1]["slug"]
    assert [base64.b64decode(t) for t in held(index)] == [(tmp_path / "site" / "models" / f"{first}.tsf").read_bytes()]
    assert f'href="models/{second}.tsf" as="fetch"' in index and f'href="models/{first}.tsf" as="fetch"' not in index
    page = (tmp_path / "site" / "p" / f"{second}.html").read_text()
    assert [base64.b64decode(t) for t in held(page)] == [(tmp_path / "site" / "models" / f"{second}.tsf").read_bytes()]


def _catalog(tmp_path, n=3):
    from tactilize.catalog import run_batch

    (tmp_path / "pics").mkdir()
    for i in range(n):
        _photo(tmp_path / "pics" / f"fabric{i}.png", size=(240, 180), seed=i)
    run_batch(str(tmp_path / "pics"), tmp_path / "cat", workers=1)
    return tmp_path / "cat"


def test_catalog_site_is_built_once_from_the_catalogues_pictures_and_says_what_it_cannot_show(tmp_path):
    from tactilize.site.from_catalog import catalog_site

    cat = _catalog(tmp_path)
    built = catalog_site(cat, cache=tmp_path / "cache")
    assert built.products == 3 and not built.missing and not built.reused and built.note(str(cat)) is None
    assert (built.folder / "index.html").is_file() and len(list((built.folder / "models").glob("*.tsf"))) == 3
    assert catalog_site(cat, cache=tmp_path / "cache").reused
    (tmp_path / "pics" / "fabric1.png").unlink()
    again = catalog_site(cat, cache=tmp_path / "cache")
    assert not again.reused and again.products == 2 and again.missing == ("fabric1.png",)
    note = again.note(str(cat))
    assert "\n" not in note and "1 of 3 products have no source picture" in note
    assert "fabric1" not in (again.folder / "index.html").read_text()


def test_catalog_site_renders_each_row_as_its_material(tmp_path):
    """``serve --catalog``'s /shop/: a catalogue row's material is in its model, as the batch rendered it."""
    from tactilize.catalog import run_batch
    from tactilize.site import read_model
    from tactilize.site.from_catalog import catalog_site

    _photo(tmp_path / "sheet.png", size=(240, 180))
    (tmp_path / "m.csv").write_text("id,path,width_mm,material\nalone,sheet.png,60,\nknit,sheet.png,60,fabric-knit\n"
                                    "cork,sheet.png,60,cork\n")
    run_batch(str(tmp_path / "m.csv"), tmp_path / "cat", profile="surface", workers=1)
    built = catalog_site(tmp_path / "cat", cache=tmp_path / "cache")
    products = {p["id"]: p for p in json.loads((built.folder / "products.json").read_text())}
    header = {k: read_model(built.folder / "models" / f"{p['slug']}.tsf").header for k, p in products.items()}
    assert {k: h["material"] for k, h in header.items()} == {"alone": None, "knit": "fabric-knit", "cork": "cork"}
    assert header["knit"]["micro"] is not None and header["knit"]["relief_scale_m"] != header["cork"]["relief_scale_m"]
    state = json.loads((built.folder / "catalog-state.json").read_text())
    assert sorted(r[5] for r in state["products"] if r[5]) == ["cork", "fabric-knit"]  # a new material builds again


def test_cli_serve_catalog_mounts_its_shop_site(tmp_path, monkeypatch):
    import tactilize.web.serve as web_serve
    from fastapi.testclient import TestClient
    from fastapi import FastAPI

    cat = _catalog(tmp_path, n=2)
    (tmp_path / "pics" / "fabric0.png").unlink()
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    seen = {}
    monkeypatch.setattr(web_serve, "serve", lambda *a, extra_routers=(), **kw: seen.setdefault("routers", list(extra_routers)))
    r = CliRunner().invoke(main, ["serve", "--catalog", str(cat), "--no-open"])
    assert r.exit_code == 0, r.output
    assert [line for line in r.stderr.splitlines() if "no source picture" in line][0].count("1 of 2") == 1
    app = FastAPI()
    for router in seen["routers"]:
        app.include_router(router)
    c = TestClient(app)
    assert "fabric1" in c.get("/shop/index.html").text and "fabric0" not in c.get("/shop/").text
    assert c.get("/api/catalog").json()["total"] == 2


def test_a_rows_given_relief_is_the_models_as_relief_mm_makes_it():
    """A row that carries ``relief_rms_m`` (as ``--relief-mm`` gives it) renders at that relief, its
    material's hardness and micro-roughness kept; without a material, the picture at that relief."""
    from tactilize.catalog import Catalog

    rng = np.random.default_rng(4)
    pixels, pitch = rng.random((300, 400)).astype(np.float32), (1e-4, 1e-4)
    for row in ({"material": "cork", "relief_rms_m": 50e-6}, {"material": "", "relief_rms_m": 20e-6}):
        choice = Catalog.choice_of(row)
        h = decode_model(model_bytes(pixels, pitch, material=choice)).header
        server = surface_model(pixels, pitch_m=pitch, material=row["material"] or None, relief_rms_m=row["relief_rms_m"])
        assert h["relief_scale_m"] == server.relief.scale_m and h["material"] == (row["material"] or None)
        assert (h["micro"] is None) == (server.micro is None)
    assert Catalog.choice_of({"material": None}).picture_only and Catalog.choice_of({}).picture_only
