"""The stroke log survives a server restart, in a real headless Chromium.

The server (``tactilize experiment run``) is killed with SIGKILL in the middle
of a trial and started again on the same port.  The page must say that the pen
is not live and hold the rating meanwhile, reconnect by itself, and every stored
sample must sit under the trial and image it was taken in (none moved to the
next trial or to another picture), with the trial marked interrupted.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time

import pytest

from _layout import settled_box

from tactilize.experiments.labdata import trial_events
from tactilize.experiments.protocols import load_protocol
from tactilize.experiments.store import Store

CHROMIUM_ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(proto, db, port):
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "tactilize.cli", "experiment", "run", str(proto), "--db", str(db), "--port", str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    lines = []
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if re.search(r"participant\s+http://127\.0\.0\.1:\d+/experiment/", line):
            return proc
    proc.kill()
    raise AssertionError("server did not start:\n" + "".join(lines))


def _two_trial_protocol(tmp_path):
    text = load_protocol("h-law").text.replace("min_stroke_s = 5.0", "min_stroke_s = 0.3")
    text = text.replace("break_every = 4", "break_every = 0")
    head, _, _ = text.partition("[[conditions]]")
    _, _, questions = text.partition("[[questions]]")
    proto = tmp_path / "two-trials.toml"
    proto.write_text(head + '[[conditions]]\nid = "D"\nlabel = "k3 = 40"\n'
                     'width = { law = "linear", k3 = 40.0, l = 0.0, unit_s = 1e-5 }\n\n'
                     '[[conditions]]\nid = "E"\nlabel = "k3 = 50"\n'
                     'width = { law = "linear", k3 = 50.0, l = 0.0, unit_s = 1e-5 }\n\n[[questions]]' + questions)
    return proto


def _stroke(page, n=30):
    box = settled_box(page, "#surface")
    page.mouse.move(box["x"] + 20, box["y"] + box["height"] / 2)
    page.mouse.down()
    for k in range(n):
        page.mouse.move(box["x"] + 20 + (k % 15) * (box["width"] - 40) / 15, box["y"] + box["height"] / 2 + (k % 3))
        page.wait_for_timeout(16)
    page.mouse.up()


def _to_first_trial(page, port, participant):
    """Consent, calibration, and the first of two trials with the pen's socket live."""
    from playwright.sync_api import expect

    page.goto(f"http://127.0.0.1:{port}/experiment/")
    page.fill("#participant-id", participant)
    page.check("#consent")
    page.click("#start")
    page.check("#felt")
    page.click("#calibrate")
    expect(page.locator("#trial-title")).to_have_text("Trial 1 of 2")
    page.wait_for_function("document.body.dataset.pen === 'live'")


@pytest.mark.browser
def test_kill_mid_trial_reconnects_and_keeps_every_sample_in_its_trial(tmp_path):
    from playwright.sync_api import expect, sync_playwright

    proto, db, port = _two_trial_protocol(tmp_path), tmp_path / "restart.sqlite3", _free_port()
    proc = _start(proto, db, port)
    now = "() => performance.now() / 1000"
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1200, "height": 900})
                errors = []
                page.on("pageerror", lambda e: errors.append(str(e)))
                _to_first_trial(page, port, "R01")
                tabs = page.locator("#tabs button")
                first, second = tabs.nth(0).get_attribute("data-image"), tabs.nth(1).get_attribute("data-image")

                _stroke(page)
                page.wait_for_function("Number(document.body.dataset.wsMessages || 0) > 0")
                page.wait_for_timeout(200)
                killed_at = page.evaluate(now)
                proc.send_signal(signal.SIGKILL)
                proc.wait(timeout=10)

                # The page knows at once: the pen is not live, the rating waits.
                page.wait_for_function("document.body.dataset.pen === 'down'")
                expect(page.locator("#pen-status")).to_be_visible()
                tabs.nth(1).click()
                _stroke(page)  # taken while the server is down: queued under trial 1, image 2
                page.check('#answers input[name="comfort"][value="5"]')
                expect(page.locator("#submit")).to_be_disabled()
                page.wait_for_function("Number(document.body.dataset.wsRetries || 0) >= 2")

                proc = _start(proto, db, port)
                page.wait_for_function("document.body.dataset.pen === 'live'", timeout=20000)
                expect(page.locator("#pen-status")).to_be_hidden()
                expect(page.locator("#submit")).to_be_enabled()  # the queue is flushed

                # A failed request says so in words, not the browser's "Failed to fetch".
                page.route("**/answers", lambda route: route.abort())
                page.click("#submit")
                expect(page.locator("#message")).to_contain_text("cannot be reached")
                assert "Failed to fetch" not in page.locator("#message").inner_text()
                page.unroute("**/answers")
                page.click("#submit")
                expect(page.locator("#trial-title")).to_have_text("Trial 2 of 2")
                trial2_at = page.evaluate(now)
                _stroke(page)
                page.check('#answers input[name="comfort"][value="3"]')
                page.click("#submit")
                expect(page.locator("#state-done")).to_be_visible()
                assert errors == []
            finally:
                browser.close()
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()

    store = Store(str(db), must_exist=True)
    rows = store.answer_rows()
    assert [(r["trial"], r["rating"]) for r in rows] == [(0, 5), (1, 3)]  # nothing lost, nothing twice
    strokes = store.stroke_rows()
    t1 = [s for s in strokes if s["trial"] == 0]
    t2 = [s for s in strokes if s["trial"] == 1]
    assert t1 and t2
    # Every sample has its own trial's timestamps: none of trial 1 moved into trial 2.
    assert max(s["t_s"] for s in t1) < trial2_at <= min(s["t_s"] for s in t2)
    # And its own image: before the kill the first picture, during the outage the second.
    assert {s["image"] for s in t1 if s["t_s"] < killed_at} == {first}
    outage = [s for s in t1 if s["t_s"] > killed_at]
    assert len(outage) > 10 and {s["image"] for s in outage} == {second}
    assert len({(s["trial"], s["t_s"], s["image"]) for s in strokes}) == len(strokes)  # none twice
    events = trial_events(store)
    assert [(e["trial"], e["kind"]) for e in events] == [(0, "interrupted")]
    assert events[0]["detail"]["gap_s"] > 0
    assert [r["stroke_interrupted"] for r in __import__("tactilize.experiments.analysis", fromlist=["x"])
            .tidy_answers(store).to_dict("records")] == [True, False]


@pytest.mark.browser
def test_an_answer_refused_with_503_is_kept_and_sent_again(tmp_path):
    """A full disk answers 503 (tests/test_experiments_disk_full.py); the page keeps the answer and resends it."""
    from playwright.sync_api import expect, sync_playwright

    proto, db, port = _two_trial_protocol(tmp_path), tmp_path / "resend.sqlite3", _free_port()
    proc = _start(proto, db, port)
    refused = []

    def full_disk(route):
        if len(refused) < 2:  # the disk is full for the first two tries
            refused.append(route.request.post_data)
            route.fulfill(status=503, content_type="application/json",
                          body='{"error": "the database cannot store this now (database or disk is full)", '
                               '"source": "store", "retry": true}')
        else:
            route.continue_()

    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1200, "height": 900})
                errors = []
                page.on("pageerror", lambda e: errors.append(str(e)))
                _to_first_trial(page, port, "R02")
                _stroke(page)
                page.locator("#tabs button").nth(1).click()
                _stroke(page)
                page.check('#answers input[name="comfort"][value="4"]')
                page.route("**/answers", full_disk)
                page.click("#submit")  # one click: the page does the rest
                expect(page.locator("#message")).to_contain_text("kept and sent again")
                expect(page.locator("#trial-title")).to_have_text("Trial 2 of 2", timeout=30000)
                assert len(refused) == 2 and refused[0] == refused[1]  # the same answer each time
                assert errors == []
            finally:
                browser.close()
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
    rows = Store(str(db), must_exist=True).answer_rows()
    assert [(r["trial"], r["rating"]) for r in rows] == [(0, 4)]
