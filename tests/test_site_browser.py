"""The built shop site in headless Chromium: one rule in two languages, and a good guest on a phone.

* Parity: strokes generated here (straight, curved, reversing, varying speed), cut into
  4 ms and 16 ms batches, run through the JavaScript rule (``surface-rule.js``) in the
  page and through the Python renderer (``tactilize.pen.replay.replay_stroke`` on the
  model file's own heights): the same events, within 1 ms and 0.02 strength.
* A phone (Chromium's mobile emulation, 390 x 844, touch): nothing vibrates before the
  element's toggle is tapped; a finger stroke then calls ``navigator.vibrate`` with valid
  patterns (on-times at least vibrate.js's shortest, at most 99 entries); at rest it is
  silent; the touch is taken only on the photo (the page scrolls elsewhere); every
  request goes to the site's own static files.
"""

from __future__ import annotations

import contextlib
import functools
import http.server
import json
import math
import os
import shutil
import threading
import time

import numpy as np
import pytest
from PIL import Image

from tactilize.pen.replay import replay_stroke
from tactilize.pen.samples import PenSample
from tactilize.site import build_site, read_model

from test_browser import CHROMIUM, CHROMIUM_ARGS

pytestmark = pytest.mark.browser

CSS_PX_M = 0.0254 / 96
#: vibrate.js's shortest on-time [ms] and Chromium's longest pattern (docs/references.md, section 5).
MIN_ON_MS = 10
PATTERN_MAX = 99

RECORD = """
window.__vibrations = [];
navigator.vibrate = function (pattern) {
  window.__vibrations.push({ t: performance.now(), pattern: Array.isArray(pattern) ? Array.from(pattern) : [pattern] });
  return true;
};
"""


def photo(path, period_px, seed, size=(2000, 1500)):
    """A photo-like picture: shading, a woven texture of ``period_px``, grain noise."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0 : size[1], 0 : size[0]]
    g = (0.5 + 0.1 * np.sin(x / 300) + 0.25 * np.sin(2 * np.pi * x / period_px) * np.sin(2 * np.pi * y / (1.3 * period_px))
         + 0.05 * rng.standard_normal((size[1], size[0])))
    rgb = (np.clip(np.stack([g, 0.9 * g, 0.8 * g], -1), 0, 1) * 255).astype(np.uint8)
    Image.fromarray(rgb).save(path, quality=90)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    root = tmp_path_factory.mktemp("shop")
    (root / "photos").mkdir()
    for name, period, seed in (("linen", 41, 1), ("corduroy", 23, 2), ("canvas", 60, 3)):
        photo(root / "photos" / f"{name}.jpg", period, seed)
    (root / "shop.csv").write_text("id,path,width_mm,material\nlinen,photos/linen.jpg,200,fabric-woven\n"
                                   "corduroy,photos/corduroy.jpg,150,fabric-corduroy\ncanvas,photos/canvas.jpg,,\n")
    summary = build_site(str(root / "shop.csv"), root / "site")
    return root / "site", summary


@contextlib.contextmanager
def _served(folder):
    """A static server of ``folder`` on a free port: its base URL."""
    handler = functools.partial(_Quiet, directory=str(folder))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}"
    finally:
        httpd.shutdown()


@pytest.fixture(scope="module")
def base(site):
    with _served(site[0]) as url:
        yield url


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


@pytest.fixture(scope="module")
def pw():
    if not (os.path.exists(CHROMIUM) or shutil.which(CHROMIUM)):
        pytest.fail(f"Chromium not found at {CHROMIUM}: the browser tests need it")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield p, b
        b.close()


# ------------------------------------------------------------------ strokes


def strokes(width_m, height_m):
    """Named strokes (t [s], x [m], y [m]) at 240 Hz across a picture ``width_m`` x ``height_m``."""
    out = {}
    t = np.arange(0.0, 0.8, 1 / 240)
    out["straight"] = (t, 0.1 * width_m + 0.08 * t, np.full_like(t, 0.5 * height_m))
    a = 0.25 * np.pi + 1.2 * t  # an arc of radius 40 % of the height
    r = 0.4 * height_m
    out["curved"] = (t, 0.5 * width_m + r * np.cos(a), 0.5 * height_m + r * np.sin(a))
    # Back and forth, stopping at each end (minimum-jerk moves): reversals.
    pts = [0.3 * width_m, 0.6 * width_m, 0.35 * width_m, 0.55 * width_m]
    tt, xx = [], []
    t0 = 0.0
    for p0, p1 in zip(pts[:-1], pts[1:]):
        u = np.arange(0.0, 0.35, 1 / 240) / 0.35
        tt += list(t0 + u * 0.35)
        xx += list(p0 + (p1 - p0) * (10 * u**3 - 15 * u**4 + 6 * u**5))
        t0 += 0.35 + 1 / 240
    tr = np.array(tt)
    out["reversing"] = (tr, np.array(xx), np.full_like(tr, 0.4 * height_m))
    # Speed from 20 to 140 mm/s and back.
    v = 0.08 + 0.06 * np.sin(2 * np.pi * t / 0.8)
    out["varying"] = (t, 0.1 * width_m + np.cumsum(v) / 240, 0.3 * height_m + 0.002 * np.sin(9 * t))
    return out


def test_js_rule_equals_python_rule(site, base, pw):
    """The JavaScript rule fires the Python renderer's events: within 1 ms and 0.02 strength."""
    out, summary = site
    page = pw[1].new_page()
    try:
        page.goto(base + "/index.html")
        checked = 0
        for p in summary.products:
            model = read_model(out / "models" / f"{p['slug']}.tsf")
            cols, rows = model.header["cols"], model.header["rows"]
            pitch = 340 * CSS_PX_M / cols  # shown 340 CSS px wide, as on a phone
            surface = model.surface(pitch)
            for name, (t, x, y) in strokes(cols * pitch, rows * pitch).items():
                t = t + 1234.5  # a page clock far from 0
                samples = [PenSample(float(a), float(b), float(c), None) for a, b, c in zip(t, x, y)]
                for batch_s in (0.004, 0.016):
                    py = replay_stroke(surface, samples, batch_s=batch_s)
                    js = page.evaluate(
                        """async ([url, pitch, rows, batchS]) => {
                            const r = await import('/surface-rule.js');
                            const m = await r.parseModel(await (await fetch(url)).arrayBuffer());
                            return r.replayStroke(m, [pitch, pitch], rows.map((s) => ({t: s[0], x: s[1], y: s[2], p: null})), batchS)
                              .map((e) => [e.t, e.s]);
                        }""", [f"/models/{p['slug']}.tsf", pitch, [[s.t_s, s.x_m, s.y_m] for s in samples], batch_s])
                    where = f"{p['id']} {name} {batch_s * 1e3:.0f} ms batches"
                    assert len(py) >= 5, f"{where}: too few bumps to compare ({len(py)})"
                    assert len(js) == len(py), f"{where}: {len(js)} events in JS, {len(py)} in Python"
                    dt = max(abs(a[0] - b.t_s) for a, b in zip(js, py))
                    ds = max(abs(a[1] - b.strength) for a, b in zip(js, py))
                    assert dt <= 1e-3 and ds <= 0.02, f"{where}: |dt| {dt * 1e3:.3f} ms, |ds| {ds:.4f}"
                    checked += 1
        assert checked == len(summary.products) * 8
    finally:
        page.close()


@pytest.fixture(scope="module")
def material_site(tmp_path_factory):
    """One woven photo as knit and as granite; a flat sheet under uneven light alone and as polished metal."""
    from test_materials import _lit_flat_metal

    root = tmp_path_factory.mktemp("materials")
    photo(root / "weave.jpg", 41, 4)
    Image.fromarray((_lit_flat_metal() * 255).round().astype(np.uint8)).save(root / "sheet.png")
    (root / "shop.csv").write_text("id,path,width_mm,material\nweave-knit,weave.jpg,200,fabric-knit\n"
                                   "weave-granite,weave.jpg,200,stone-granite\nsheet-alone,sheet.png,100,\n"
                                   "sheet-polished,sheet.png,100,metal-polished\n")
    summary = build_site(str(root / "shop.csv"), root / "site")
    with _served(root / "site") as url:
        yield root / "site", summary, url


def test_a_material_product_feels_on_the_page_as_the_server_renders_it(material_site, pw):
    """Two rows of one photo, two materials: different events on the page, each the Python renderer's
    for that photo and material (its micro-roughness drawn as Python draws it); polished metal on a lit
    flat sheet is silent where the sheet alone is not, replayed and under a finger."""
    import dataclasses

    out, summary, url = material_site
    page = pw[1].new_page()
    felt = {}
    try:
        page.goto(url + "/index.html")
        for p in summary.products:
            model = read_model(out / "models" / f"{p['slug']}.tsf")
            cols, rows = model.header["cols"], model.header["rows"]
            pitch = 340 * CSS_PX_M / cols
            surface = model.surface(pitch)
            for name, (t, x, y) in strokes(cols * pitch, rows * pitch).items():
                samples = [PenSample(float(a), float(b), float(c), None) for a, b, c in zip(t + 1234.5, x, y)]
                py = replay_stroke(surface, samples)
                js = page.evaluate(
                    """async ([url, pitch, rows]) => {
                        const r = await import('/surface-rule.js');
                        const m = await r.parseModel(await (await fetch(url)).arrayBuffer());
                        return r.replayStroke(m, [pitch, pitch], rows.map((s) => ({t: s[0], x: s[1], y: s[2], p: null})))
                          .map((e) => [e.t, e.s]);
                    }""", [f"/models/{p['slug']}.tsf", pitch, [[s.t_s, s.x_m, s.y_m] for s in samples]])
                where = f"{p['id']} {name}"
                assert len(js) == len(py), f"{where}: {len(js)} events in JS, {len(py)} in Python"
                if py:
                    dt = max(abs(a[0] - b.t_s) for a, b in zip(js, py))
                    ds = max(abs(a[1] - b.strength) for a, b in zip(js, py))
                    assert dt <= 1e-3 and ds <= 0.02, f"{where}: |dt| {dt * 1e3:.3f} ms, |ds| {ds:.4f}"
                felt[p["id"], name] = py
                if p["id"] == "weave-granite":
                    # Its micro-roughness is felt: without it the events would be others.
                    bare = replay_stroke(dataclasses.replace(surface, micro=None), samples)
                    assert [e.t_s for e in bare] != [e.t_s for e in py], where
    finally:
        page.close()
    names = ("straight", "curved", "reversing", "varying")
    for name in names:
        knit, granite = felt["weave-knit", name], felt["weave-granite", name]
        assert len(knit) >= 5 and len(granite) >= 5, name
        assert len(knit) != len(granite) or max(abs(a.strength - b.strength) for a, b in zip(knit, granite)) > 0.1, name
        assert felt["sheet-polished", name] == [] and len(felt["sheet-alone", name]) >= 5, name
    # Under a finger on the phone: the polished sheet's page renders no event, the sheet alone's does.
    ctx = phone(pw)
    try:
        counts = {}
        for ident in ("sheet-polished", "sheet-alone"):
            slug = next(p["slug"] for p in summary.products if p["id"] == ident)
            pg = ctx.new_page()
            pg.goto(f"{url}/p/{slug}.html")
            ready(pg)
            b = pg.locator("tactile-surface .pic").bounding_box()
            Finger(pg).stroke(b["x"] + 20, b["y"] + 0.5 * b["height"], b["x"] + b["width"] - 20, 0.6)
            pg.wait_for_timeout(100)
            counts[ident] = pg.evaluate("[document.querySelector('tactile-surface').stats.batches, "
                                        "document.querySelector('tactile-surface').stats.events]")
            pg.close()
    finally:
        ctx.close()
    assert counts["sheet-polished"][0] > 5 and counts["sheet-polished"][1] == 0, counts
    assert counts["sheet-alone"][1] > 0, counts


def test_inflate_equals_zlib(site, base, pw):
    """The page's own inflater gives zlib's bytes for every block type, and refuses damaged streams."""
    import zlib

    rng = np.random.default_rng(9)
    texts = {
        "stored (noise)": rng.integers(0, 256, 70_000, dtype=np.uint8).tobytes(),
        "fixed codes (short)": b"tactile surface " * 3,
        "dynamic codes, long matches": bytes(50_000) + bytes(range(256)) * 40,
        "model residuals": (rng.normal(0, 6, 80_000).round().astype(np.int64) & 0xFF).astype(np.uint8).tobytes(),
        "empty": b"",
    }
    cases = [(name, zlib.compress(data, level), data) for name, data in texts.items() for level in (1, 9)]
    page = pw[1].new_page()
    try:
        page.goto(base + "/index.html")
        for name, packed, data in cases:
            got = page.evaluate("""async ([packed, size]) => { const r = await import('/surface-rule.js');
                return Array.from(r.inflate(new Uint8Array(packed), size)); }""", [list(packed), len(data)])
            assert bytes(got) == data, name
        packed = zlib.compress(texts["model residuals"], 9)
        for damaged in (packed[:-200], packed[:2] + bytes(len(packed) - 2), b"\x00\x00" + packed[2:]):
            err = page.evaluate("""async ([packed, size]) => { const r = await import('/surface-rule.js');
                try { r.inflate(new Uint8Array(packed), size); return null; } catch (e) { return e.message; } }""",
                                [list(damaged), 80_000])
            assert err and "damaged" in err, err
    finally:
        page.close()


def test_wavelet_rows_equal_python(site, base, pw):
    """The page's wavelets for a batch's events are Python's ``wavelet_rows``."""
    from tactilize.surface.events import PulseEvent
    from tactilize.synthesis.wavelets import wavelet_rows

    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.0005, 0.06, 40)) + 10.0
    s = rng.uniform(0, 1, 40)
    py = wavelet_rows([PulseEvent(float(a), float(b)) for a, b in zip(t, s)], 10.01)
    page = pw[1].new_page()
    try:
        page.goto(base + "/index.html")
        js = page.evaluate("""async ([t, s]) => { const r = await import('/surface-rule.js');
            return r.waveletRows(t.map((v, i) => ({t: v, s: s[i]})), 10.01, [20, 1000]); }""", [t.tolist(), s.tolist()])
    finally:
        page.close()
    assert np.allclose(np.array(js), np.array(py), rtol=0, atol=1e-12)


# ------------------------------------------------------------------ the phone


def phone(pw, init_script=RECORD):
    p, b = pw
    d = dict(p.devices["Pixel 7"])
    d.pop("default_browser_type", None)
    d["viewport"] = {"width": 390, "height": 844}
    ctx = b.new_context(**d)
    if init_script:
        ctx.add_init_script(init_script)
    return ctx


class Finger:
    """Trusted touch events through the DevTools protocol, each with its own timestamp."""

    def __init__(self, page):
        self.cdp = page.context.new_cdp_session(page)

    def send(self, kind, x, y, at_s):
        points = [] if kind == "touchEnd" else [{"x": x, "y": y, "radiusX": 3, "radiusY": 3, "force": 0.5, "id": 1}]
        self.cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points, "timestamp": at_s})

    def swipe_up(self, x, y, distance_px, duration_s=0.3):
        e0 = time.time()
        self.send("touchStart", x, y, e0)
        for i in range(1, 20):
            self.send("touchMove", x, y - distance_px * i / 19, e0 + duration_s * i / 19)
            time.sleep(duration_s / 19)
        self.send("touchEnd", x, y - distance_px, e0 + duration_s)

    def stroke(self, x0, y0, x1, duration_s, interval_s=0.008, lift=True):
        e0, t0 = time.time(), time.perf_counter()
        self.send("touchStart", x0, y0, e0)
        while (t := time.perf_counter() - t0) < duration_s:
            self.send("touchMove", x0 + (x1 - x0) * t / duration_s, y0, e0 + t)
            time.sleep(interval_s)
        self.x, self.y = x1, y0
        if lift:
            self.send("touchEnd", x1, y0, time.time())


def ready(page, selector="tactile-surface"):
    page.wait_for_function(f"document.querySelector('{selector}') && document.querySelector('{selector}').model !== null",
                           timeout=15000)


def test_phone_stroke_vibrates_validly_and_only_when_asked(site, base, pw):
    out, summary = site
    slug = summary.products[0]["slug"]
    ctx = phone(pw)
    requests = []
    ctx.on("request", lambda r: requests.append(r.url))
    page = ctx.new_page()
    try:
        page.goto(f"{base}/p/{slug}.html")
        el = page.locator("tactile-surface")
        el.scroll_into_view_if_needed()
        ready(page)
        b = page.locator("tactile-surface .pic").bounding_box()
        finger = Finger(page)
        y = b["y"] + 0.5 * b["height"]
        # Before the toggle: the stroke is rendered, the motor never asked.
        finger.stroke(b["x"] + 20, y, b["x"] + b["width"] - 20, 0.6)
        assert page.evaluate("document.querySelector('tactile-surface').stats.events") > 0
        assert page.evaluate("window.__vibrations.length") == 0, "vibrated before being asked to"
        toggle = page.locator("tactile-surface button.vib")
        assert toggle.is_visible(), "the phone gets a visible vibrate toggle"
        page.wait_for_timeout(600)  # a tap right after a touch stroke is taken for its second tap
        toggle.tap()
        assert toggle.get_attribute("aria-pressed") == "true"
        finger.stroke(b["x"] + 20, y, b["x"] + b["width"] - 20, 0.8, lift=False)
        page.wait_for_timeout(150)
        during = page.evaluate("window.__vibrations")
        # The finger rests, then lifts: nothing new may start.
        page.wait_for_timeout(500)
        settled = len(page.evaluate("window.__vibrations"))
        page.wait_for_timeout(500)
        finger.send("touchEnd", finger.x, finger.y, time.time())
        page.wait_for_timeout(400)
        after = page.evaluate("window.__vibrations")
    finally:
        ctx.close()
    patterns = [v["pattern"] for v in during if v["pattern"] != [0]]
    assert patterns, "a touch stroke with vibration on never called navigator.vibrate"
    for pat in patterns:
        assert 1 <= len(pat) <= PATTERN_MAX, pat
        assert all(isinstance(v, int) and v >= 1 for v in pat), pat
        assert all(on >= MIN_ON_MS for on in pat[0::2]), f"an on-time below {MIN_ON_MS} ms: {pat}"
    late = [v["pattern"] for v in after[settled:] if v["pattern"] != [0]]
    assert not late, f"vibrated at rest: {late}"
    foreign = [u for u in requests if not u.startswith(base + "/")]
    assert not foreign, f"requests beyond the site's own files: {foreign}"
    assert all(u.split("?")[0].rsplit(".", 1)[-1] in ("html", "css", "js", "jpg") for u in requests), requests
    # The product page holds its model: it is decoded from the page, never fetched.
    assert not [u for u in requests if u.endswith(".tsf")], requests


def test_touch_taken_only_on_the_photo_and_several_products_on_a_page(site, base, pw):
    out, summary = site
    ctx = phone(pw)
    requests = []
    ctx.on("request", lambda r: requests.append(r.url))
    page = ctx.new_page()
    try:
        page.goto(base + "/index.html")
        n = page.locator("tactile-surface").count()
        assert n == len(summary.products) >= 3
        styles = page.evaluate("""() => { const el = document.querySelector('tactile-surface');
            return [getComputedStyle(el.shadowRoot.querySelector('.pic')).touchAction, getComputedStyle(el).touchAction,
                    getComputedStyle(document.body).touchAction,
                    getComputedStyle(el.shadowRoot.querySelector('.bar')).touchAction]; }""")
        assert styles == ["none", "auto", "auto", "auto"], styles
        # A swipe on the page's heading scrolls the page; a stroke on a photo does not.
        h = page.locator(".product h2").first.bounding_box()
        Finger(page).swipe_up(h["x"] + 10, h["y"] + 5, 220)
        page.wait_for_timeout(300)
        scrolled = page.evaluate("window.scrollY")
        assert scrolled > 50, f"the page did not scroll from a swipe outside the photos ({scrolled})"
        # Stroke the second product: only it renders.
        second = page.locator("tactile-surface").nth(1)
        second.scroll_into_view_if_needed()
        page.wait_for_function("document.querySelectorAll('tactile-surface')[1].model !== null", timeout=15000)
        b = page.locator("tactile-surface >> nth=1").locator(".pic").bounding_box()
        before = page.evaluate("window.scrollY")
        Finger(page).stroke(b["x"] + 20, b["y"] + b["height"] / 2, b["x"] + b["width"] - 20, 0.5)
        page.wait_for_timeout(100)
        stats = page.evaluate("[...document.querySelectorAll('tactile-surface')].map((e) => e.stats.batches)")
        assert stats[1] > 5 and stats[0] == 0 and stats[2] == 0, stats
        assert abs(page.evaluate("window.scrollY") - before) < 1, "a stroke on a photo scrolled the page"
    finally:
        ctx.close()
    # The first card's model is in the page; the others' preloads are the element's own loads, not a second copy.
    models = [u for u in requests if u.endswith(".tsf")]
    assert not [u for u in models if summary.products[0]["slug"] in u], models
    assert models and len(models) == len(set(models)), models


def test_a_hand_written_page_needs_no_build_step_and_starts_no_output_unasked(site, base, pw):
    """The shop's own page, as someone writes it: one module tag, two elements from the copied files.
    No bundler and no bare import (every import is a relative file); only the site's files requested;
    no audio context and no vibration until their toggles are tapped."""
    import re

    out, summary = site
    for js in out.glob("*.js"):
        specs = re.findall(r"""(?:import|from)\s*\(?\s*["']([^"']+)["']""", js.read_text())
        assert all(s.startswith("./") for s in specs), f"{js.name} imports {specs}"
    a, b = summary.products[0]["slug"], summary.products[1]["slug"]
    (out / "embed").mkdir(exist_ok=True)
    (out / "embed" / "plain.html").write_text(
        '<!doctype html>\n<meta name="viewport" content="width=device-width, initial-scale=1">\n<p>Our fabrics</p>\n'
        '<script type="module" src="../tactile-surface.js"></script>\n'
        f'<tactile-surface model="../models/{a}.tsf" image="../img/{a}.jpg" label="A"></tactile-surface>\n'
        f'<tactile-surface model="../models/{b}.tsf" image="../img/{b}.jpg" label="B"></tactile-surface>\n')
    ctx = phone(pw, RECORD + """
window.__audio = 0;
const Real = window.AudioContext;
window.AudioContext = class extends Real { constructor(...a) { super(...a); window.__audio++; } };
""")
    requests = []
    ctx.on("request", lambda r: requests.append(r.url))
    page = ctx.new_page()
    try:
        page.goto(base + "/embed/plain.html")
        page.wait_for_function("[...document.querySelectorAll('tactile-surface')].every((e) => e.model !== null)", timeout=15000)
        second = page.locator("tactile-surface").nth(1)
        second.scroll_into_view_if_needed()
        box = second.locator(".pic").bounding_box()
        Finger(page).stroke(box["x"] + 20, box["y"] + box["height"] / 2, box["x"] + box["width"] - 20, 0.5)
        page.wait_for_timeout(100)
        stats = page.evaluate("[...document.querySelectorAll('tactile-surface')].map((e) => [e.stats.batches, e.stats.events])")
        assert stats[0][0] == 0 and stats[1][0] > 5 and stats[1][1] > 0, stats
        assert page.evaluate("[window.__audio, window.__vibrations.length]") == [0, 0], "an output started unasked"
        sound = second.locator("button.snd")
        assert sound.is_visible()
        page.wait_for_timeout(600)
        sound.tap()
        page.wait_for_function("window.__audio === 1", timeout=5000)
    finally:
        ctx.close()
    foreign = [u for u in requests if not u.startswith(base + "/")]
    assert not foreign, f"requests beyond the site's own files: {foreign}"
    kinds = {u.split("?")[0].rsplit(".", 1)[-1] for u in requests}
    assert kinds <= {"html", "js", "tsf", "jpg"}, requests
