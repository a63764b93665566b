"""Screenshots of the pen page for docs/serve.md, from the real page in headless Chromium.

Starts ``tactilize serve`` on a free loopback port, opens the page at a laptop
size (1280 x 800), a tablet in portrait (820 x 1180) and a phone (390 x 844, in
Chromium's mobile emulation with touch), strokes the picture with trusted pen
or touch events (Chrome DevTools Protocol, as the browser tests do) and saves
PNGs::

    python scripts/serve_screenshots.py            # into docs/img/
    python scripts/serve_screenshots.py --out /tmp/shots
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time

CHROMIUM = os.environ.get("TACTILIZE_CHROMIUM", "/usr/bin/chromium")
ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run", "--hide-scrollbars"]
SHOTS = [
    # (file, viewport, view, texture, phone: None | "first-visit" | "calibrated")
    ("serve-1280x800.png", (1280, 800), "single", "corduroy", None),
    ("serve-six-1280x800.png", (1280, 800), "six", None, None),
    ("serve-tablet-portrait.png", (820, 1180), "single", "patchwork", None),
    # A phone's first visit: the calibration prompt and the surface saying what to do.
    ("serve-phone-first-visit.png", (390, 844), "single", "corduroy", "first-visit"),
    # Calibrated (0.16 mm per CSS px) and stroked with a finger: the drive in view under the surface.
    ("serve-phone-390x844.png", (390, 844), "single", "linen", "calibrated"),
]
#: A phone's screen: what Playwright's "iPhone 13"-like descriptors give (3 device px per CSS px).
PHONE = dict(device_scale_factor=3, is_mobile=True, has_touch=True,
             user_agent="Mozilla/5.0 (Linux; Android 14; Pixel 8) AppleWebKit/537.36 (KHTML, like Gecko) "
                        "Chrome/126.0 Mobile Safari/537.36")
PHONE_MM_PER_PX = 0.16


def start_server():
    proc = subprocess.Popen([sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    m = re.search(r"http://127\.0\.0\.1:\d+/", proc.stdout.readline())
    if not m:
        proc.kill()
        raise SystemExit("tactilize serve did not start")
    return proc, m.group(0)


def stroke(page, dx_px: float, seconds: float = 0.6, y_frac: float = 0.3):
    """A pen stroke to the right across the surface, held down at the end (the drive shows)."""
    cdp = page.context.new_cdp_session(page)
    box = page.locator("#frame").bounding_box()
    x0, y = box["x"] + 20, box["y"] + box["height"] * y_frac

    def ev(kind, x, buttons):
        cdp.send("Input.dispatchMouseEvent", {"type": kind, "x": x, "y": y, "button": "left", "buttons": buttons,
                                              "clickCount": 0 if kind == "mouseMoved" else 1, "pointerType": "pen",
                                              "force": 0.6, "tiltX": 10, "tiltY": -5})

    ev("mousePressed", x0, 1)
    t0 = time.perf_counter()
    while (t := time.perf_counter() - t0) < seconds:
        ev("mouseMoved", x0 + dx_px * t / seconds, 1)
        time.sleep(0.004)
    return cdp


def touch_stroke(page, dx_px: float, seconds: float = 0.6, y_frac: float = 0.4):
    """A finger stroke to the right across the surface, held down at the end (trusted touch events)."""
    cdp = page.context.new_cdp_session(page)
    box = page.locator("#surface").bounding_box()
    x0, y = box["x"] + 15, box["y"] + box["height"] * y_frac

    def ev(kind, x):
        points = [] if kind == "touchEnd" else [{"x": x, "y": y, "radiusX": 4, "radiusY": 4, "force": 0.5, "id": 1}]
        cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points})

    ev("touchStart", x0)
    t0 = time.perf_counter()
    while (t := time.perf_counter() - t0) < seconds:
        ev("touchMove", x0 + dx_px * t / seconds)
        time.sleep(0.008)
    return cdp


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "img"))
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    from playwright.sync_api import sync_playwright

    server, url = start_server()
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            for name, (w, h), view, texture, phone in SHOTS:
                ctx = browser.new_context(viewport={"width": w, "height": h}, **(PHONE if phone else {}))
                if phone == "calibrated":
                    # Saved as the dialog saves it: mm per device pixel.
                    ctx.add_init_script("localStorage.setItem('tactilize.calibration.v1', JSON.stringify("
                                        f"{{mm_per_device_px: {PHONE_MM_PER_PX} / 3, dpr: 3}}))")
                page = ctx.new_page()
                page.goto(url)
                page.wait_for_selector("body[data-ready=true]", timeout=30_000)
                page.wait_for_function("window.tactilize.settings && window.tactilize.settings.texture", timeout=30_000)
                if view == "six":
                    page.get_by_test_id("view-six").check()
                    page.wait_for_function("window.tactilize.settings.composite", timeout=10_000)
                else:
                    page.locator(f'[data-testid=texture][data-id="{texture}"]').click()
                    page.wait_for_function(f"window.tactilize.settings.texture === '{texture}'")
                page.wait_for_function("document.querySelector('#spectrum-fs').textContent !== '–'", timeout=20_000)
                # Picking a texture low in the gallery scrolls the page: back to the surface.
                page.evaluate("window.scrollTo(0, 0)")
                page.wait_for_timeout(300)
                if phone == "first-visit":
                    page.wait_for_timeout(300)
                    page.screenshot(path=os.path.join(args.out, name), scale="css")
                    print(os.path.join(args.out, name))
                    ctx.close()
                    continue
                width = page.locator("#surface").bounding_box()["width"]
                dx = min(width - 40, 700)
                mm = page.evaluate("window.tactilize.mmPerPx")
                if phone:
                    touch_stroke(page, dx, seconds=dx * mm / 60.0)  # about 60 mm/s
                else:
                    stroke(page, dx, seconds=dx * mm / 100.0)  # about 100 mm/s
                # The page as it was with the pen moving: a pen at rest for 80 ms is rendered
                # at speed 0 (and some profiles go quiet then), and a screenshot (three device
                # pixels per CSS pixel on the phone) can take longer than that.  So the page
                # stops reading drives now; what it shows is the moving pen's.
                page.evaluate("window.tactilize.ws.onmessage = null")
                page.screenshot(path=os.path.join(args.out, name), scale="css")
                print(os.path.join(args.out, name))
                ctx.close()
            browser.close()
    finally:
        server.terminate()
        server.communicate(timeout=10)


if __name__ == "__main__":
    main()
