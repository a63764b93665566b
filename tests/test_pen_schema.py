"""One pen socket schema for both pages, one parser behind both handlers, constants served from Python.

The pen page (``/ws``) and the experiment's page (``/experiment/ws/{session}``)
send the same sample message (tactilize.web.rows: positions in mm on the
picture, times in ms, pressure and tilt, a batch id), parsed by
:func:`tactilize.web.rows.pen_batch`; the numbers the pages need from the
server's rules come from ``api/constants``, not from copies in JavaScript.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from _layout import settled_box
from fastapi.testclient import TestClient

import tactilize.experiments.strokes as strokes_mod
import tactilize.web.rows as rows_mod
import tactilize.web.session as session_mod
from tactilize.experiments import Flow, Store, experiment_router, load_protocol
from tactilize.pen.display import CARD_MM, MM_PER_PX_RANGE
from tactilize.synthesis import wavelets
from tactilize.web import create_app
from tactilize.web.constants import page_constants

from _experiment_socket import open_session, until
from test_experiments_browser import CHROMIUM_ARGS, server  # noqa: F401  (the fixture)
from test_web import FakeOutput, hello, recv_type

LOCAL = "http://127.0.0.1"
STATIC = Path(rows_mod.__file__).parent / "static"
EXPERIMENT_STATIC = Path(strokes_mod.__file__).parent / "static"


@pytest.fixture()
def both(tmp_path):
    """The pen app with the experiment's routes: (client, flow)."""
    flow = Flow(load_protocol("h-law"), Store(f"sqlite:///{tmp_path / 'schema.sqlite3'}"))
    app = create_app(FakeOutput(), "paper", warm=False, extra_routers=[experiment_router(flow)])
    with TestClient(app, base_url=LOCAL) as client:
        yield client, flow


def test_one_parser_is_what_both_socket_handlers_call(both, monkeypatch):
    client, _ = both
    assert session_mod.pen_batch is rows_mod.pen_batch and strokes_mod.pen_batch is rows_mod.pen_batch
    calls = []

    def spy(msg):
        calls.append(msg)
        return rows_mod.pen_batch(msg)

    monkeypatch.setattr(session_mod, "pen_batch", spy)
    monkeypatch.setattr(strokes_mod, "pen_batch", spy)
    token, trial = open_session(client)
    image = trial["images"][0]["id"]
    rows = [[1000.0 + 8 * k, 5.0 + 0.4 * k, 8.0, 0.5, 0.0, 0.0] for k in range(10)]
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws)
        ws.send_text(json.dumps({"type": "samples", "batch": "7", "samples": rows}))
        assert recv_type(ws, "drive")["batch"] == "7"
    with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
        ws.send_json({"type": "samples", "batch": "page-1", "samples": rows, "trial": trial["index"], "image": image})
        assert [m for m in until(ws, "ack") if m["type"] == "ack"][0]["batch"] == "page-1"
    assert len(calls) == 2 and calls[0]["samples"] == calls[1]["samples"]


@pytest.mark.parametrize("bad, says", [
    ({"type": "samples", "samples": [[0, 1]]}, "sample 0: a sample has 3 to 6 values"),
    ({"type": "samples", "samples": [[0, 1, 2, 7]]}, "pressure must be in [0, 1]"),
    ({"type": "samples", "batch": 12, "samples": [[0, 1, 2]]}, "'batch' must be an id"),
    ({"type": "samples", "samples": [[0, 1, 2]] * (rows_mod.MAX_BATCH + 1)}, "too many samples"),
])
def test_both_pages_get_the_same_one_line_for_a_bad_sample_message(both, bad, says):
    client, _ = both
    token, trial = open_session(client)
    with client.websocket_connect("ws://127.0.0.1/ws") as ws:
        hello(ws)
        ws.send_text(json.dumps(bad))
        pen_page = recv_type(ws, "error")["message"]
    with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
        ws.send_json({**bad, "trial": trial["index"], "image": trial["images"][0]["id"]})
        experiment_page = until(ws, "error")[-1]["error"]
    assert says in pen_page and pen_page == experiment_page


def test_the_pages_constants_are_pythons_served(both):
    client, _ = both
    served = client.get("/api/constants").json()
    assert served == page_constants()
    assert served["max_repeat"] == session_mod.MAX_REPEAT and served["card_mm"] == list(CARD_MM)
    assert served["default_mm_per_px"] == pytest.approx(rows_mod.DEFAULT_M_PER_CSS_PX * 1e3)
    assert served["mm_per_px_range"] == list(MM_PER_PX_RANGE) and served["max_batch"] == rows_mod.MAX_BATCH
    assert served["wavelet"] == {"span_sigmas": wavelets.SPAN_SIGMAS, "same_s": wavelets.SAME_S,
                                 "glide_s": wavelets.GLIDE_S, "late_sigmas": wavelets.LATE_SIGMAS}
    experiment = client.get("/experiment/api/constants").json()
    assert {k: experiment[k] for k in served} == served
    for name in ("pen-input.js", "calibrate.js", "constants.js"):  # the experiment's page uses the pen page's modules
        assert client.get(f"/experiment/static/{name}").text == (STATIC / name).read_text()


#: Numbers of the server's rules that once were copied into the pages' JavaScript.
COPIED = [r"\b85\.6", r"\b53\.98", r"25\.4\s*/\s*96", r"\b0\.2646", r"0\.5\s*/\s*300", r"GLIDE_S\s*=\s*0\.003",
          r"SPAN\s*=\s*3\b", r"MAX_REPEAT\s*=\s*64", r"\b0\.1\s*/\s*mmPerPx", r"n\s*<\s*500\b"]


def test_no_number_of_the_servers_rules_is_copied_into_the_pages():
    for path in [*STATIC.glob("*.js"), *EXPERIMENT_STATIC.glob("*.js")]:
        text = re.sub(r"//.*|/\*[\s\S]*?\*/", "", path.read_text())  # code, not comments
        for pattern in COPIED:
            assert not re.search(pattern, text), f"{path.name} copies {pattern}"


@pytest.mark.browser
def test_both_pages_send_the_same_schema_for_the_same_stroke(server):  # noqa: F811
    from playwright.sync_api import expect, sync_playwright

    url, _ = server
    root = url.removesuffix("experiment/")

    def stroke(page, selector):
        frames = []
        page.on("websocket", lambda ws: ws.on("framesent", lambda payload: frames.append(payload)))
        return frames

    def draw(page, selector):
        box = settled_box(page, selector)
        page.mouse.move(box["x"] + 20, box["y"] + 40)
        page.mouse.down()
        for k in range(30):  # 3 CSS px a step, 16 ms apart
            page.mouse.move(box["x"] + 20 + 3 * k, box["y"] + 40)
            page.wait_for_timeout(16)
        page.mouse.up()

    def batches(frames):
        docs = [json.loads(f) for f in frames if isinstance(f, str)]
        return [d for d in docs if d.get("type") == "samples"]

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        try:
            pen = browser.new_page(viewport={"width": 1280, "height": 900})
            pen_frames = stroke(pen, "#surface")
            pen.goto(root)
            pen.wait_for_function("document.body.dataset.ready === 'true' && window.tactilize.settings")
            pen_mm = pen.evaluate("window.tactilize.mmPerPx")
            # The page's constants are the server's, loaded by the calibration module.
            page_card = pen.evaluate("import('/static/calibrate.js').then((m) => m.CARD_MM)")
            assert page_card == list(CARD_MM)
            draw(pen, "#surface")
            pen.wait_for_function("window.tactilize.drives.some((d) => d.on)")

            exp = browser.new_page(viewport={"width": 1280, "height": 900})
            exp_frames = stroke(exp, "#surface")
            exp.goto(url)
            exp.fill("#participant-id", "S01")
            exp.check("#consent")
            exp.click("#start")
            expect(exp.locator("#view-calibration")).to_be_visible()
            exp.locator("#scale").evaluate("(el) => { el.value = '400'; el.dispatchEvent(new Event('input')); }")
            exp.check("#felt")
            exp.click("#calibrate")
            expect(exp.locator("#view-trial")).to_be_visible()
            exp.wait_for_function("document.body.dataset.pen === 'live'")
            exp_mm = CARD_MM[0] / 400
            draw(exp, "#surface")
            exp.wait_for_function("Number(document.body.dataset.unacked || 1) === 0 && document.body.dataset.lastDriveHz")
        finally:
            browser.close()

    for frames, mm_per_px, page_fields in ((pen_frames, pen_mm, set()), (exp_frames, exp_mm, {"trial", "image"})):
        sent = batches(frames)
        assert sent, "no sample message"
        for msg in sent:
            assert set(msg) == {"type", "batch", "samples"} | page_fields
            assert isinstance(msg["batch"], str) and 1 <= len(msg["batch"]) <= rows_mod.MAX_BATCH_ID
            assert all(rows_mod.sample_error(r) is None and len(r) == 6 for r in msg["samples"])
        rows = [r for msg in sent for r in msg["samples"]]
        t, x, y = (list(c) for c in zip(*(r[:3] for r in rows)))
        assert all(b >= a for a, b in zip(t, t[1:]))  # ms, each sample once, in order
        # Millimetres on the picture: the stroke's 87 CSS px at the page's scale, from 20 px in.
        assert x[0] == pytest.approx(20 * mm_per_px, abs=1.5 * mm_per_px)
        assert x[-1] - x[0] == pytest.approx(87 * mm_per_px, abs=3 * mm_per_px)
        assert max(y) - min(y) < 1.5 * mm_per_px
        assert 50 < t[-1] - t[0] < 60_000  # times in ms, not s
