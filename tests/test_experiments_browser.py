"""One trial in a real headless Chromium: consent, ID, calibration, stroke, answer, end.

The server is ``tactilize experiment run`` (the flow inside the pen app) in its
own process, on a free loopback port, with an SQLite file.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time

import pytest

from _layout import settled_box

from tactilize.experiments.protocols import load_protocol
from tactilize.experiments.store import Store

CHROMIUM_ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


@pytest.fixture()
def server(tmp_path):
    # A one-trial protocol file: the h-law's images and question, one condition,
    # half a second of stroking before the form opens.
    text = load_protocol("h-law").text
    text = text.replace("min_stroke_s = 5.0", "min_stroke_s = 0.5")
    head, _, _ = text.partition("[[conditions]]")
    _, _, questions = text.partition("[[questions]]")
    proto = tmp_path / "one-trial.toml"
    proto.write_text(head + '[[conditions]]\nid = "D"\nlabel = "paper"\n'
                     'width = { law = "linear", k3 = 40.0, l = 0.0, unit_s = 1e-5 }\n\n[[questions]]' + questions)
    db = tmp_path / "browser.sqlite3"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "tactilize.cli", "experiment", "run", str(proto), "--db", str(db), "--port", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    url = None
    lines = []
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and url is None:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        m = re.search(r"participant\s+(http://127\.0\.0\.1:\d+/experiment/)", line)
        if m:
            url = m.group(1)
    if url is None:
        proc.kill()
        raise AssertionError("server did not start:\n" + "".join(lines))
    yield url, db
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()


@pytest.mark.browser
def test_one_trial_in_headless_chromium(server):
    from playwright.sync_api import expect, sync_playwright

    url, db = server
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 900})
            errors = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(url)
            expect(page.locator("#view-welcome")).to_be_visible()

            # No consent: the server refuses and the page says why.
            page.fill("#participant-id", "B01")
            page.click("#start")
            expect(page.locator("#message")).to_contain_text("consent")

            page.check("#consent")
            page.click("#start")
            expect(page.locator("#view-calibration")).to_be_visible()
            page.locator("#scale").evaluate("(el) => { el.value = '400'; el.dispatchEvent(new Event('input')); }")
            assert page.locator("#card").evaluate("(el) => el.getBoundingClientRect().width") == pytest.approx(400, abs=1)
            page.check("#felt")
            page.click("#calibrate")

            expect(page.locator("#view-trial")).to_be_visible()
            expect(page.locator("#trial-title")).to_have_text("Trial 1 of 1")
            expect(page.locator("#answers")).to_be_hidden()  # not before stroking
            # The pen's socket is open and the picture laid out before the stroke (a loaded
            # machine may take a moment to load the picture, which moves the surface).
            page.wait_for_function("document.body.dataset.pen === 'live'", timeout=30_000)
            box = settled_box(page, "#surface")
            assert box and box["width"] > 100
            page.mouse.move(box["x"] + 20, box["y"] + box["height"] / 2)
            page.mouse.down()
            for k in range(60):  # about 1 s of stroking back and forth
                x = box["x"] + 20 + (k % 20) * (box["width"] - 40) / 20
                page.mouse.move(x, box["y"] + box["height"] / 2 + (k % 3))
                page.wait_for_timeout(16)
            page.mouse.up()
            expect(page.locator("#answers")).to_be_visible()
            page.wait_for_function("Number(document.body.dataset.wsMessages || 0) > 0")
            page.check('#answers input[name="comfort"][value="6"]')
            page.click("#submit")
            expect(page.locator("#state-done")).to_be_visible()
            expect(page.locator("#progress")).to_contain_text("1 of 1 done")
            assert errors == []
        finally:
            browser.close()

    store = Store(str(db))
    rows = store.answer_rows()
    assert [(r["participant"], r["question"], r["rating"]) for r in rows] == [("B01", "comfort", 6)]
    assert rows[0]["response_time_s"] > 0.5
    overview = store.sessions_overview()[0]
    assert overview["stroke_samples"] > 10 and overview["completed_at"]
    # The scale the participant set: 400 CSS px for the 85.6 mm card.
    import json
    import sqlite3

    with sqlite3.connect(db) as con:
        calib = json.loads(con.execute("select calibration_json from sessions").fetchone()[0])
    assert calib["mm_per_px"] == pytest.approx(85.6 / 400)
    strokes = store.stroke_rows()
    assert max(s["speed_m_s"] for s in strokes) > 0.01
    assert all(s["pulse_frequency_hz"] <= 300 for s in strokes)


@pytest.mark.browser
def test_the_picture_box_is_laid_out_before_the_picture_loads(server):
    # The picture's response is held until the test lets it go: the box must not move
    # when it arrives, and a stroke on the picture before it is shown logs nothing.
    import json

    from playwright.sync_api import expect, sync_playwright

    url, db = server
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 900})
            errors, held, sent = [], [], []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.route("**/api/images/**", lambda route: held.append(route))
            page.on("websocket", lambda ws: ws.on("framesent", lambda payload: sent.append(payload)))
            page.goto(url)
            page.fill("#participant-id", "B02")
            page.check("#consent")
            page.click("#start")
            expect(page.locator("#view-calibration")).to_be_visible()
            page.locator("#scale").evaluate("(el) => { el.value = '400'; el.dispatchEvent(new Event('input')); }")
            page.check("#felt")
            page.click("#calibrate")
            expect(page.locator("#view-trial")).to_be_visible()
            page.wait_for_function("document.body.dataset.pen === 'live'", timeout=30_000)
            page.wait_for_function("document.getElementById('texture').src !== ''")
            assert held and not page.locator("#texture").evaluate("(im) => im.complete && im.naturalWidth > 0")

            before = page.locator("#surface").bounding_box()
            mm_per_px = 85.6 / 400
            # The stand-in pictures are 600 x 400 px at 0.1 mm a pixel: 60 x 40 mm at true size.
            assert before["width"] == pytest.approx(60.0 / mm_per_px, abs=1)
            assert before["height"] == pytest.approx(40.0 / mm_per_px, abs=1)

            def stroke(box):
                y = box["y"] + box["height"] / 2
                page.mouse.move(box["x"] + 20, y)
                page.mouse.down()
                for k in range(1, 31):
                    page.mouse.move(box["x"] + 20 + 3 * k, y)
                    page.wait_for_timeout(16)
                page.mouse.up()

            def samples():
                docs = [json.loads(f) for f in sent if isinstance(f, str)]
                return [s for d in docs if d.get("type") == "samples" for s in d["samples"]]

            stroke(before)  # before the picture is shown
            page.wait_for_function("Number(document.body.dataset.unacked || 0) === 0")
            page.wait_for_timeout(100)  # a few of the page's 30 ms flushes
            assert samples() == []

            for route in held:
                route.continue_()
            page.unroute("**/api/images/**")
            page.wait_for_function("document.body.dataset.picture === 'shown'")
            after = page.locator("#surface").bounding_box()
            assert after == before

            stroke(after)
            page.wait_for_function("Number(document.body.dataset.unacked || 0) === 0")
            got = samples()
            assert got, "a stroke on the shown picture logs samples"
            # Offsets from the picture's corner in mm: where the pen was, 20 to 110 CSS px in.
            xs = [s[1] for s in got]
            assert min(xs) == pytest.approx(20 * mm_per_px, abs=3 * mm_per_px)
            assert max(xs) == pytest.approx(110 * mm_per_px, abs=3 * mm_per_px)
            ys = [s[2] for s in got]
            assert all(y == pytest.approx(after["height"] / 2 * mm_per_px, abs=mm_per_px) for y in ys)
            assert errors == []
        finally:
            browser.close()
