"""Screenshots of the pen page for docs/serve.md, from the real page in headless Chromium.

Starts ``tactilize serve`` on a free loopback port, opens the page at a laptop
size (1280 x 800) and a tablet in portrait (820 x 1180), strokes the picture
with trusted pen events (Chrome DevTools Protocol, as the browser tests do) and
saves PNGs::

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
    # (file, viewport, view, texture)
    ("serve-1280x800.png", (1280, 800), "single", "corduroy"),
    ("serve-six-1280x800.png", (1280, 800), "six", None),
    ("serve-tablet-portrait.png", (820, 1180), "single", "patchwork"),
]


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
            for name, (w, h), view, texture in SHOTS:
                page = browser.new_page(viewport={"width": w, "height": h})
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
                width = page.locator("#frame").bounding_box()["width"]
                dx = min(width - 40, 700)
                stroke(page, dx, seconds=dx * 0.2646 / 100.0)  # about 100 mm/s
                # At once, with the pen still down and moving: a pen at rest for 80 ms is
                # rendered at speed 0 (and some profiles go quiet then).
                page.screenshot(path=os.path.join(args.out, name))
                print(os.path.join(args.out, name))
                page.close()
            browser.close()
    finally:
        server.terminate()
        server.communicate(timeout=10)


if __name__ == "__main__":
    main()
