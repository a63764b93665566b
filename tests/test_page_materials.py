"""The page's material picker, end to end in headless Chromium, and its routes in-process
(docs/serve.md, "Materials"; docs/surfaces.md, "Materials").

The browser test picks a material, uploads a flat metal sheet photographed under uneven
light and strokes it: as ``metal-polished`` the server renders no bumps; as the picture
alone its lighting is felt.  The server is ``tactilize serve`` with its default (surface)
profile.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tactilize.data import png_bytes
from tactilize.web import create_app

from test_browser import Pen, browser, opened_page, serving, surface_box  # noqa: F401  (the fixture)
from test_materials import _lit_flat_metal
from test_web import FakeOutput


@pytest.fixture(scope="module")
def surface_server(tmp_path_factory):
    with serving(tmp_path_factory) as url:
        yield url


def _events_of_a_stroke(page) -> int:
    """Stroke the shown picture left to right (about 100 mm/s) and count the bumps the
    server scheduled for it."""
    pen = Pen(page)
    box = surface_box(page)
    seq0 = page.evaluate("window.tactilize.seq")
    x, y = box["x"] + 20, box["y"] + min(box["height"] / 2, 120)
    # Position and timestamp from one clock reading: the speed is exact however the
    # events are paced (a stroke with no bumps shows no drive to wait for).
    epoch0 = time.time()
    pen._send("mousePressed", x, y, 1, at_s=epoch0)
    while (t := time.time() - epoch0) < 0.8:
        pen._send("mouseMoved", x + 380.0 * t, y, 1, at_s=epoch0 + t)
        time.sleep(0.004)
    pen.lift(x + 380.0 * t, y)
    page.wait_for_function(f"window.tactilize.seq > {seq0} && window.tactilize.lastDrive && "
                           "window.tactilize.lastDrive.seq >= window.tactilize.seq", timeout=10_000)
    drives = page.evaluate(f"window.tactilize.drives.filter(d => d.seq > {seq0})")
    assert drives and all(d.get("rendering") == "surface" for d in drives)
    return sum(int(d.get("events") or 0) for d in drives)


@pytest.mark.browser
def test_the_picker_renders_an_upload_as_the_material_and_says_so(browser, surface_server, tmp_path):  # noqa: F811
    metal = tmp_path / "metal.png"
    metal.write_bytes(png_bytes((_lit_flat_metal() * 255).astype(np.uint8), 96.0))
    with opened_page(browser, surface_server) as page:
        assert page.get_by_test_id("rendered-as").text_content() == "rendered as: picture only"
        names = page.eval_on_selector_all("#material option", "os => os.map(o => o.value)")
        assert names[0] == "" and "metal-polished" in names and "stone-granite" in names
        page.get_by_test_id("material").select_option("metal-polished")
        page.get_by_test_id("upload").set_input_files(str(metal))
        page.locator("#upload-width").fill("50")
        page.locator("#upload-form button[type=submit]").click()
        page.wait_for_function("window.tactilize.settings && (window.tactilize.settings.texture || '').startsWith('upload-')",
                               timeout=30_000)
        line = page.get_by_test_id("rendered-as").text_content()
        assert line.startswith("rendered as: metal-polished (relief 50 nm RMS"), line
        page.wait_for_function("document.querySelector('#picture').complete")
        assert _events_of_a_stroke(page) == 0  # under the least felt bump everywhere

        # The same picture alone: its lighting is read as relief.
        page.get_by_test_id("material").select_option("")
        page.wait_for_function("(window.tactilize.settings.texture || '').endsWith('~picture')", timeout=30_000)
        assert page.get_by_test_id("rendered-as").text_content() == "rendered as: picture only"
        assert _events_of_a_stroke(page) > 3


# ------------------------------------------------------------------- the routes, in-process


@pytest.fixture(scope="module")
def client():
    with TestClient(create_app(FakeOutput(), "surface", output_name="fake", warm=False, material="stone-granite"),
                    base_url="http://127.0.0.1") as c:
        yield c


def test_the_servers_material_renders_the_built_ins_and_the_picker_lists_the_library(client):
    doc = client.get("/api/materials").json()
    assert doc["default"] == "stone-granite" and doc["default_rendered_as"].startswith("stone-granite (relief ")
    assert {m["name"] for m in doc["materials"]} >= {"metal-polished", "fabric-knit", "sandpaper-p80"}
    first = client.get("/api/textures").json()[0]
    assert first["material"] == "stone-granite" and first["base"] == first["id"]
    state = client.app.state.tactilize
    assert state.texture(first["id"]).surface.relief.material.name == "stone-granite"


def test_a_picture_rendered_as_another_material_is_its_own_entry(client):
    tid = client.get("/api/textures").json()[0]["id"]
    r = client.post(f"/api/textures/{tid}/rendered", json={"material": "fabric-knit"})
    assert r.status_code == 200, r.text
    doc = r.json()
    assert doc["id"] == f"{tid}~fabric-knit" and doc["base"] == tid and doc["material"] == "fabric-knit"
    assert doc["rendered_as"].startswith("fabric-knit (relief 0.12 mm RMS")
    state = client.app.state.tactilize
    knit, granite = state.texture(doc["id"]).surface, state.texture(tid).surface
    assert knit.relief.material.name == "fabric-knit" and granite.relief.material.name == "stone-granite"
    assert not np.array_equal(knit.height, granite.height)
    alone = client.post(f"/api/textures/{doc['id']}/rendered", json={"material": None}).json()
    assert alone["id"] == f"{tid}~picture" and alone["rendered_as"] == "picture only"
    assert state.texture(alone["id"]).surface.relief is None
    # Asking for the picture's own material gives the picture's own entry back.
    assert client.post(f"/api/textures/{doc['id']}/rendered", json={"material": "stone-granite"}).json()["id"] == tid


def test_an_unknown_material_is_a_422_naming_it(client):
    tid = client.get("/api/textures").json()[0]["id"]
    r = client.post(f"/api/textures/{tid}/rendered", json={"material": "graniet"})
    assert r.status_code == 422 and "graniet" in r.json()["error"] and "stone-granite" in r.json()["error"]
    r = client.post("/api/textures/nope/rendered", json={"material": "glass"})
    assert r.status_code == 404
    png = png_bytes((_lit_flat_metal()[:64, :64] * 255).astype(np.uint8), 96.0)
    r = client.post("/api/textures", files={"file": ("m.png", png, "image/png")}, data={"material": "metal-polishd"})
    assert r.status_code == 422 and "metal-polishd" in r.json()["error"]


def test_an_upload_takes_the_material_sent_with_it(client):
    png = png_bytes((_lit_flat_metal()[:80, :80] * 255).astype(np.uint8), 96.0)
    state = client.app.state.tactilize
    sent = client.post("/api/textures", files={"file": ("m.png", png, "image/png")},
                       data={"width_mm": "10", "material": "metal-polished"}).json()
    assert sent["material"] == "metal-polished" and state.texture(sent["id"]).surface.relief.material.name == "metal-polished"
    alone = client.post("/api/textures", files={"file": ("m.png", png, "image/png")},
                        data={"width_mm": "10", "material": ""}).json()
    assert alone["id"] != sent["id"] and alone["rendered_as"] == "picture only"
    default = client.post("/api/textures", files={"file": ("m.png", png, "image/png")}, data={"width_mm": "10"}).json()
    assert default["material"] == "stone-granite"  # the server's, when the form names none
