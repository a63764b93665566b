"""The catalog read API: a product's tactile profile by id and its exports (AHAP, Android, WAV)."""

from __future__ import annotations

import io
import math
import wave

import numpy as np
import pytest
from PIL import Image

pytest.importorskip("httpx")
from fastapi.testclient import TestClient  # noqa: E402

from tactilize.catalog import run_batch  # noqa: E402
from tactilize.catalog.api import catalog_router, create_catalog_app  # noqa: E402
from tactilize.features import extract_features  # noqa: E402
from tactilize.image import load_image  # noqa: E402
from tactilize.mapping import Profile  # noqa: E402

GOOD = ["shirts/linen.png", "shirts/denim.png", "sofa.png", "rug.jpg", "flat.png"]


def _picture(period_px: float, angle_deg: float, contrast: float, size: int = 96) -> np.ndarray:
    rows, cols = np.mgrid[0:size, 0:size]
    t = math.radians(angle_deg)
    a = 0.5 + 0.5 * contrast * np.cos(2 * np.pi * (cols * math.cos(t) - rows * math.sin(t)) / period_px)
    return (np.clip(a, 0, 1) * 255).astype(np.uint8)


@pytest.fixture(scope="module")
def shop(tmp_path_factory):
    root = tmp_path_factory.mktemp("api_shop")
    (root / "shirts").mkdir()
    Image.fromarray(_picture(4, 0, 0.9)).save(root / "shirts" / "linen.png")
    Image.fromarray(_picture(12, 60, 0.6)).save(root / "shirts" / "denim.png")
    Image.fromarray(_picture(24, 90, 0.8)).save(root / "sofa.png")
    Image.fromarray(_picture(7, 135, 0.7)).convert("RGB").save(root / "rug.jpg", quality=95)
    Image.fromarray(np.full((64, 64), 128, np.uint8)).save(root / "flat.png")  # no texture at all
    (root / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 20)
    return root


@pytest.fixture(scope="module", params=["parquet", "sql"])
def client(request, shop, tmp_path_factory):
    out_dir = tmp_path_factory.mktemp("api_out")
    out = out_dir / "cat.parquet" if request.param == "parquet" else f"sqlite:///{out_dir / 'cat.db'}"
    summary = run_batch(shop, out, profile="paper", workers=1)
    assert (summary.ok, summary.failed) == (len(GOOD), 1)
    return TestClient(create_catalog_app(out))


def test_catalog_info_and_pages(client):
    info = client.get("/api/catalog").json()
    assert info == {"profile": "paper", "speeds_mm_s": [30.0, 60.0, 120.0], "total": 6, "ok": 5, "failed": 1}
    page = client.get("/api/catalog/products", params={"limit": 3}).json()
    assert page["ids"] == sorted(GOOD + ["broken.png"])[:3]
    assert client.get("/api/catalog/products", params={"status": "error"}).json()["ids"] == ["broken.png"]
    assert client.get("/api/catalog/products", params={"limit": 0}).status_code == 422


def test_profile_by_id_matches_the_library(client, shop):
    prof = Profile.preset("paper")
    for ident in GOOD:
        r = client.get(f"/api/catalog/products/{ident}")  # ids with "/" work as they are
        assert r.status_code == 200, r.text
        doc = r.json()
        feat = extract_features(load_image(shop / ident))
        assert doc["id"] == ident and doc["status"] == "ok" and doc["error"] is None and doc["profile"] == "paper"
        assert doc["features"]["spatial_frequency_per_m"] == pytest.approx(feat.spatial_frequency_per_m, rel=1e-9)
        assert doc["features"]["spectral_intensity"] == pytest.approx(feat.spectral_intensity, rel=1e-9)
        assert doc["image"]["width_px"] == load_image(shop / ident).shape[1]
        assert doc["texture_map"]["grid_rows"] >= 1
        assert [d["speed_mm_s"] for d in doc["drives"]] == [30.0, 60.0, 120.0]
        for d in doc["drives"]:
            drv = prof.drive(feat, speed_m_s=d["speed_mm_s"] * 1e-3)
            assert d["pulse_frequency_hz"] == pytest.approx(drv.pulse_frequency_hz, rel=1e-9)
            assert d["pulse_width_s"] == pytest.approx(drv.pulse_width_s, rel=1e-9)
            assert d["clamped"] == list(drv.clamped)
    flat = client.get("/api/catalog/products/flat.png").json()
    assert flat["features"]["has_peak"] is False and all(d["pulse_frequency_hz"] == 0 for d in flat["drives"])


def test_drive_at_any_speed(client, shop):
    feat = extract_features(load_image(shop / "sofa.png"))
    for speed_mm_s in (0.0, 12.5, 60.0, 400.0):
        d = client.get("/api/catalog/products/sofa.png/drive", params={"speed_mm_s": speed_mm_s}).json()
        drv = Profile.preset("paper").drive(feat, speed_m_s=speed_mm_s * 1e-3)
        assert d["speed_mm_s"] == pytest.approx(speed_mm_s)
        assert d["pulse_frequency_hz"] == pytest.approx(drv.pulse_frequency_hz, rel=1e-9)
        assert d["duty_ratio"] == pytest.approx(drv.duty_ratio, rel=1e-9)
    assert client.get("/api/catalog/products/sofa.png/drive", params={"speed_mm_s": -1}).status_code == 422


def test_failed_and_unknown_products(client):
    doc = client.get("/api/catalog/products/broken.png").json()
    assert doc["status"] == "error" and doc["error"] and doc["drives"] == []
    for tail in ("drive", "export/ahap", "export/android", "export/wav"):
        r = client.get(f"/api/catalog/products/broken.png/{tail}")
        assert r.status_code == 409 and "broken.png" in r.json()["error"]
        assert client.get(f"/api/catalog/products/nope.png/{tail}").status_code == 404
    assert client.get("/api/catalog/products/nope.png").status_code == 404


def test_ahap_export(client):
    r = client.get("/api/catalog/products/shirts/denim.png/export/ahap", params={"speed_mm_s": 30, "duration_s": 0.5})
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/json")
    assert ".ahap" in r.headers.get("content-disposition", "")
    doc = r.json()
    assert "Version" in doc and isinstance(doc["Pattern"], list) and doc["Pattern"]
    events = [p["Event"] for p in doc["Pattern"] if "Event" in p]
    assert events and all(e["EventType"] in ("HapticContinuous", "HapticTransient") for e in events)
    for e in events:
        params = {p["ParameterID"]: p["ParameterValue"] for p in e["EventParameters"]}
        assert 0 <= params["HapticIntensity"] <= 1 and 0 <= params["HapticSharpness"] <= 1
        assert 0 <= e["Time"] <= 0.5 + 1e-9


def test_android_export(client):
    r = client.get("/api/catalog/products/shirts/linen.png/export/android", params={"duration_s": 0.25})
    assert r.status_code == 200
    doc = r.json()
    timings, amps = doc["timings_ms"], doc["amplitudes"]
    assert len(timings) == len(amps) >= 1
    assert all(t >= 0 for t in timings) and all(0 <= a <= 255 for a in amps) and max(amps) > 0
    assert sum(timings) == pytest.approx(250, abs=15)


def test_wav_export(client):
    r = client.get(
        "/api/catalog/products/rug.jpg/export/wav", params={"speed_mm_s": 60, "duration_s": 0.2, "sample_rate_hz": 16000}
    )
    assert r.status_code == 200 and r.headers["content-type"] == "audio/wav"
    with wave.open(io.BytesIO(r.content)) as w:
        assert (w.getnchannels(), w.getsampwidth(), w.getframerate()) == (1, 2, 16000)
        assert w.getnframes() == 3200
        pcm = np.frombuffer(w.readframes(w.getnframes()), "<i2")
    assert np.abs(pcm).max() > 1000  # the pulses are there, not silence


def test_openapi_describes_the_routes(client):
    spec = client.get("/openapi.json").json()
    paths = spec["paths"]
    base = "/api/catalog/products/{product_id}"
    for path in (base, base + "/drive", base + "/export/ahap", base + "/export/android", base + "/export/wav"):
        assert "get" in paths[path], path
    assert "audio/wav" in paths[base + "/export/wav"]["get"]["responses"]["200"]["content"]
    assert "404" in paths[base]["get"]["responses"]
    assert "TactileProfile" in spec["components"]["schemas"]


def test_router_mounts_in_another_app(shop, tmp_path):
    from fastapi import FastAPI

    out = tmp_path / "c.parquet"
    run_batch(shop, out, profile="paper", workers=1)
    app = FastAPI()
    app.include_router(catalog_router(out, prefix="/shop"))
    r = TestClient(app).get("/shop/products/sofa.png")
    assert r.status_code == 200 and r.json()["status"] == "ok"


def test_serve_has_a_catalog_option():
    from click.testing import CliRunner

    from tactilize.cli import main

    res = CliRunner().invoke(main, ["serve", "--help"])
    assert res.exit_code == 0 and "--catalog" in res.output
    res = CliRunner().invoke(main, ["serve", "--catalog", "/nonexistent/catalog", "--port", "0", "--no-open"])
    assert res.exit_code == 2 and "not a catalog" in res.stderr


def test_exports_are_those_of_the_export_module(client, shop, tmp_path):
    from tactilize.export import ahap_pattern, android_waveform, export_wav

    feat = extract_features(load_image(shop / "shirts" / "denim.png"))
    drv = Profile.preset("paper").drive(feat, speed_m_s=0.045)
    q = {"speed_mm_s": 45, "duration_s": 0.3}
    base = "/api/catalog/products/shirts/denim.png/export"
    assert client.get(f"{base}/ahap", params=q).json() == ahap_pattern(drv, 0.3)
    android = client.get(f"{base}/android", params=q).json()
    reference = android_waveform(drv, 0.3)
    assert android["timings_ms"] == reference["timings_ms"] and android["amplitudes"] == reference["amplitudes"]
    wav = client.get(f"{base}/wav", params={**q, "sample_rate_hz": 8000}).content
    assert wav == export_wav(drv, tmp_path / "d.wav", 0.3, 8000).read_bytes()


def test_any_registry_format_is_served(client):
    from tactilize.export import read_haptic, read_hjif

    base = "/api/catalog/products/shirts/denim.png/export"
    r = client.get(f"{base}/hjif", params={"speed_mm_s": 60, "duration_s": 0.5})
    assert r.status_code == 200 and ".hjif" in r.headers["content-disposition"]
    drive = client.get("/api/catalog/products/shirts/denim.png/drive", params={"speed_mm_s": 60}).json()
    track = read_hjif(r.content)
    f = [p.frequency_hz for p in track.points] + [p.frequency_hz for p in track.taps]
    assert f and all(x == pytest.approx(drive["pulse_frequency_hz"], rel=0.01) for x in f)
    r = client.get(f"{base}/haptic", params={"duration_s": 0.5})
    assert r.status_code == 200 and (read_haptic(r.content).points or read_haptic(r.content).taps)
    r = client.get(f"{base}/mp3")
    assert r.status_code == 404 and "unknown export format" in r.json()["error"]


def test_a_rows_material_renders_its_drive_and_exports(tmp_path):
    """A surface catalogue of one lit flat sheet, alone, as granite and as polished metal: the API's
    drive at any speed is what ``--material`` renders for the picture, and its exports follow."""
    from test_materials import _lit_flat_metal

    from tactilize.surface.rendering import rendering_for

    sheet = (_lit_flat_metal() * 255).round().astype(np.uint8)
    Image.fromarray(sheet).save(tmp_path / "sheet.png")
    (tmp_path / "m.csv").write_text("id,path,width_mm,material\nalone,sheet.png,50,\ngranite,sheet.png,50,stone-granite\n"
                                    "polished,sheet.png,50,metal-polished\n")
    run_batch(str(tmp_path / "m.csv"), tmp_path / "cat", profile="surface", workers=1)
    c = TestClient(create_catalog_app(tmp_path / "cat"))
    doc = c.get("/api/catalog/products/granite").json()
    assert doc["material"] == "stone-granite" and doc["rendered_as"].startswith("stone-granite (relief ")
    assert "material" not in doc["features"]
    assert c.get("/api/catalog/products/alone").json()["rendered_as"] == "picture only"
    prof, img = Profile.preset("surface"), load_image(tmp_path / "sheet.png", width_mm=50)
    feat = extract_features(img)
    rates = {}
    for ident, material in (("alone", None), ("granite", "stone-granite"), ("polished", "metal-polished")):
        expected = rendering_for(prof, image=img, material=material).steady_drive(feat, 0.045)
        d = c.get(f"/api/catalog/products/{ident}/drive", params={"speed_mm_s": 45}).json()
        assert d["pulse_frequency_hz"] == pytest.approx(expected.pulse_frequency_hz, rel=1e-6), ident
        assert d["amplitude"] == pytest.approx(expected.amplitude, rel=1e-6, abs=1e-9), ident
        rates[ident] = d["pulse_frequency_hz"]
    # Polished metal is below the least felt bump; granite and the picture alone are not, and differ.
    assert rates["polished"] == 0.0 and rates["granite"] > 5.0 and rates["alone"] > 5.0
    assert rates["granite"] != pytest.approx(rates["alone"], rel=0.01), rates
    q = {"speed_mm_s": 45, "duration_s": 0.3, "sample_rate_hz": 8000}
    silent = c.get("/api/catalog/products/polished/export/wav", params=q).content
    felt = c.get("/api/catalog/products/granite/export/wav", params=q).content
    assert np.abs(np.frombuffer(silent[44:], "<i2")).max(initial=0) == 0
    assert np.abs(np.frombuffer(felt[44:], "<i2")).max() > 1000
