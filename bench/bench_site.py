"""The shop site on a slow phone: how soon a stroke renders, how fast a pointer event reaches the outputs,
and whether the page still scrolls smoothly (docs/shop.md, "Measured").

Builds a site of three generated 2000 x 1500 photos (a manifest: two of them of a material,
fabric-woven and fabric-corduroy, one the picture alone), prints each product's model file
size, serves it with Python's own ``http.server``, and opens the fabric-woven product's page
(its micro-roughness drawn where the pen is) in headless Chromium's mobile emulation (Pixel 7 at
390 x 844, touch) with the CPU slowed 4 times (CDP ``Emulation.setCPUThrottlingRate``):

* **first stroke**: a stroke started by the page at its ``load`` event (pointer events
  dispatched from an init script); the time from ``load`` to the element's first rendered
  batch [ms];
* **event to outputs**: trusted touch strokes (CDP) with the vibration toggle on (the motor
  recorded, not driven) and the sound on; per batch, the time from the newest sample's
  ``timeStamp`` to the events handed to the motor and the audio worklet, p50 / p99 [ms];
  and per pulse event, how long before its bump is crossed it first reached them [ms];
* **scroll**: animation-frame intervals while a finger swipes the product grid, and while
  a finger strokes a photo: p50 / p99 [ms], frames over 33 ms, long tasks (> 50 ms).

Prints figures, asserts nothing::

    PYTHONPATH=src python bench/bench_site.py [--throttle 4] [--seconds 3] [--loads 10]
"""

from __future__ import annotations

import argparse
import functools
import http.server
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from PIL import Image

CHROMIUM = os.environ.get("TACTILIZE_CHROMIUM", "/usr/bin/chromium")
ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", "--autoplay-policy=no-user-gesture-required"]

RECORD = """
window.__vibrations = [];
navigator.vibrate = (p) => { window.__vibrations.push(p); return true; };
window.__frames = []; window.__long = 0;
(function tick(t) { window.__frames.push(t); if (window.__frames.length > 20000) window.__frames.splice(0, 10000);
  requestAnimationFrame(tick); })(0);
try { new PerformanceObserver((l) => { window.__long += l.getEntries().length; }).observe({ type: "longtask" }); } catch (e) {}
"""

# A stroke the page itself starts at its load event: the first batch's render time is what we read.
STROKE_AT_LOAD = """
addEventListener("load", () => {
  window.__loadAt = performance.now();
  const el = document.querySelector("tactile-surface");
  const pic = el.shadowRoot.querySelector(".pic"), r = pic.getBoundingClientRect();
  const type = "onpointerrawupdate" in window ? "pointerrawupdate" : "pointermove";
  const at = (x) => ({ pointerId: 7, pointerType: "touch", isPrimary: true, clientX: r.left + x, clientY: r.top + r.height / 2,
    pressure: 0.5, bubbles: true, composed: true });
  pic.dispatchEvent(new PointerEvent("pointerdown", at(20)));
  let i = 0;
  const step = () => { pic.dispatchEvent(new PointerEvent(type, at(20 + 3 * ++i))); if (i < 60) setTimeout(step, 8); };
  setTimeout(step, 8);
});
"""


def photo(path: Path, period: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:1500, 0:2000]
    g = 0.5 + 0.1 * np.sin(x / 300) + 0.25 * np.sin(2 * np.pi * x / period) * np.sin(2 * np.pi * y / (1.3 * period))
    g = g + 0.05 * rng.standard_normal(g.shape)
    rgb = (np.clip(np.stack([g, 0.9 * g, 0.8 * g], -1), 0, 1) * 255).astype(np.uint8)
    Image.fromarray(rgb).save(path, quality=90)


class Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):  # noqa: D401 - the bench prints its own lines
        pass


def finger(page):
    cdp = page.context.new_cdp_session(page)

    def send(kind, x, y, at):
        pts = [] if kind == "touchEnd" else [{"x": x, "y": y, "radiusX": 3, "radiusY": 3, "force": 0.5, "id": 1}]
        cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": pts, "timestamp": at})

    return send


def frames(page) -> tuple[float, float, int]:
    f = np.diff(np.array(page.evaluate("window.__frames.splice(0)"))[1:])
    f = f[f > 0]
    if not f.size:
        return float("nan"), float("nan"), 0
    return float(np.percentile(f, 50)), float(np.percentile(f, 99)), int((f > 33.4).sum())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--throttle", type=float, default=4.0)
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--loads", type=int, default=10, help="page loads for the first-stroke figure")
    a = ap.parse_args()
    from playwright.sync_api import sync_playwright

    from tactilize.site import build_site
    from tactilize.site.builder import static_files

    import gzip

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        (root / "ph").mkdir()
        for name, period, seed in (("linen", 41, 1), ("corduroy", 23, 2), ("canvas", 60, 3)):
            photo(root / "ph" / f"{name}.jpg", period, seed)
        (root / "shop.csv").write_text("id,path,width_mm,material\nlinen,ph/linen.jpg,200,fabric-woven\n"
                                       "corduroy,ph/corduroy.jpg,150,fabric-corduroy\ncanvas,ph/canvas.jpg,,\n")
        summary = build_site(str(root / "shop.csv"), root / "site")
        js = sum(len(gzip.compress(f.read_bytes(), 9)) for f in static_files() if f.suffix == ".js")
        sizes = ", ".join(f"{q['id']} ({q.get('material') or 'picture only'}) {q['model_bytes'] / 1024:.1f}"
                          for q in summary.products)
        print(f"weight: tactile-surface.js and its imports {js / 1024:.1f} KB gzipped (goal <= 30); "
              f"models {sizes} KB for 2000 px photos (goal <= 64)")
        httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(root / "site")))
        threading.Thread(target=httpd.serve_forever, daemon=True).start()
        base = f"http://127.0.0.1:{httpd.server_address[1]}"
        slug = next(q["slug"] for q in summary.products if q["id"] == "linen")
        with sync_playwright() as p:
            b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            d = dict(p.devices["Pixel 7"])
            d.pop("default_browser_type", None)
            d["viewport"] = {"width": 390, "height": 844}

            def page_with(script):
                ctx = b.new_context(**d)
                ctx.add_init_script(RECORD + script)
                pg = ctx.new_page()
                pg.context.new_cdp_session(pg).send("Emulation.setCPUThrottlingRate", {"rate": a.throttle})
                return ctx, pg

            # 1. The first stroke, started at the load event.
            firsts, models = [], []
            for _ in range(a.loads):
                ctx, pg = page_with(STROKE_AT_LOAD)
                pg.goto(f"{base}/p/{slug}.html")
                pg.wait_for_function("document.querySelector('tactile-surface').stats.firstRenderMs !== null", timeout=20000)
                firsts.append(pg.evaluate("document.querySelector('tactile-surface').stats.firstRenderMs - window.__loadAt"))
                models.append(pg.evaluate("document.querySelector('tactile-surface').stats.modelMs - window.__loadAt"))
                ctx.close()
            print(f"first stroke rendered after the load event ({a.throttle:g}x CPU throttling, {a.loads} loads): "
                  f"p50 {np.percentile(firsts, 50):.0f} ms, max {max(firsts):.0f} ms (goal <= 100): "
                  f"{', '.join(f'{v:.0f}' for v in firsts)} ms; the model was ready at "
                  f"{', '.join(f'{v:.0f}' for v in models)} ms")

            # 2. Event to outputs, with the motor and the sound on.
            ctx, pg = page_with("")
            pg.goto(f"{base}/p/{slug}.html")
            pg.wait_for_function("document.querySelector('tactile-surface').model !== null", timeout=20000)
            pg.locator("tactile-surface button.vib").tap()
            pg.locator("tactile-surface button.snd").tap()
            pg.wait_for_timeout(300)
            box = pg.locator("tactile-surface .pic").bounding_box()
            send = finger(pg)
            pg.evaluate("window.__frames.splice(0); window.__long = 0")
            t_end = time.perf_counter() + a.seconds
            while time.perf_counter() < t_end:
                e0, t0 = time.time(), time.perf_counter()
                y = box["y"] + box["height"] * (0.3 + 0.4 * np.random.rand())
                send("touchStart", box["x"] + 15, y, e0)
                while (t := time.perf_counter() - t0) < 0.5:
                    send("touchMove", box["x"] + 15 + (box["width"] - 30) * t / 0.5, y, e0 + t)
                    time.sleep(0.004)
                send("touchEnd", box["x"] + box["width"] - 15, y, time.time())
                time.sleep(0.1)
            st = pg.evaluate("document.querySelector('tactile-surface').stats")
            lat = np.array(st["latencyMs"])
            work = np.array(st["workMs"])
            f50, f99, slow = frames(pg)
            long_stroke = pg.evaluate("window.__long")
            vib = pg.evaluate("window.__vibrations.length")
            print(f"pointer event to motor and audio scheduled, from the event's timeStamp: p50 {np.percentile(lat, 50):.2f} ms, "
                  f"p99 {np.percentile(lat, 99):.2f} ms; the element's own work: p50 {np.percentile(work, 50):.2f} ms, "
                  f"p99 {np.percentile(work, 99):.2f} ms ({lat.size} batches, {st['events']} events, "
                  f"{vib} vibrate calls; goal p99 <= 16)")
            lead = np.array(st["leadMs"])
            print(f"each pulse event first handed to the outputs, before its bump is crossed: p50 {np.percentile(lead, 50):.1f} ms, "
                  f"p1 {np.percentile(lead, 1):.1f} ms ahead; {(lead >= 0).mean() * 100:.0f} % ahead of time, "
                  f"the rest at most {max(0.0, -lead.min()):.1f} ms late ({lead.size} events)")
            print(f"frames while stroking a photo: p50 {f50:.1f} ms, p99 {f99:.1f} ms, {slow} over 33 ms, "
                  f"{long_stroke} long tasks")
            ctx.close()

            # 3. The page's own scroll with its products loaded.
            ctx, pg = page_with("")
            pg.goto(f"{base}/index.html")
            pg.wait_for_function("[...document.querySelectorAll('tactile-surface')].every((e) => e.model !== null)",
                                 timeout=20000)
            send = finger(pg)
            pg.evaluate("window.__frames.splice(0); window.__long = 0")
            scrolled = 0.0
            for k in range(int(a.seconds / 0.6)):
                e0 = time.time()
                x, y0 = 6.0, 600.0  # the grid's margin, beside the photos
                send("touchStart", x, y0, e0)
                for i in range(1, 31):
                    send("touchMove", x, y0 - (300 if k % 2 == 0 else -300) * i / 30, e0 + 0.4 * i / 30)
                    time.sleep(0.4 / 30)
                send("touchEnd", x, y0, e0 + 0.45)
                time.sleep(0.2)
                scrolled += abs(pg.evaluate("scrollY"))
            f50, f99, slow = frames(pg)
            print(f"frames while a finger scrolls the grid: p50 {f50:.1f} ms, p99 {f99:.1f} ms, {slow} over 33 ms, "
                  f"{pg.evaluate('window.__long')} long tasks (the page scrolled: {scrolled > 0})")
            ctx.close()
            b.close()
        httpd.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
