"""The pen page's stroke export: the HTTP route and, in Chromium, "Download stroke" and "Export this stroke"."""

from __future__ import annotations

import csv
import io
import json

import pytest
from fastapi.testclient import TestClient

from tactilize.export import read_ahap, read_hjif
from tactilize.actuators.recording import RecordingOutput
from tactilize.web import create_app


@pytest.fixture(scope="module")
def client():
    with TestClient(create_app(RecordingOutput(), "paper", output_name="recorder", warm=False), base_url="http://127.0.0.1") as c:
        yield c


def _rows(v_mm_s=40.0, n=120, rate=240.0, x0=5.0, y0=10.0):
    return [[i / rate, x0 + v_mm_s * i / rate, y0, 0.5] for i in range(n)]


def test_formats_are_the_registry(client):
    from tactilize.export import FORMATS

    names = [f["name"] for f in client.get("/api/export/formats").json()]
    assert names == list(FORMATS)


def test_export_route_answers_the_file(client):
    r = client.post("/api/export/stroke", json={"texture": "corduroy", "format": "hjif", "samples": _rows()})
    assert r.status_code == 200, r.text
    assert 'filename="stroke-corduroy.hjif"' in r.headers["content-disposition"]
    track = read_hjif(r.content)
    assert track.channels == 2 and track.points and all(p.frequency_hz > 0 for p in track.points)
    # the same stroke slower: a lower frequency (the pen server's laws ran)
    r_slow = client.post("/api/export/stroke", json={"texture": "corduroy", "format": "ahap", "samples": _rows(10.0)})
    assert r_slow.status_code == 200, r_slow.text
    slow = read_ahap(r_slow.content)
    assert max(p.frequency_hz for p in track.points) > max([p.frequency_hz for p in slow.points] + [0.0])


def test_export_route_plays_the_bumps_of_the_surface_rendering(client):
    """With the surface profile the route exports the texture's bumps, as the library does offline."""
    from tactilize.export import parse_stroke, run_stroke
    from tactilize.export.events import HJIF_TRANSIENT_S, plan_events
    from tactilize.mapping import Profile

    rows = _rows(v_mm_s=15.0, n=240)
    r = client.post("/api/export/stroke", json={"texture": "corduroy", "format": "hjif", "samples": rows,
                                                "profile": "surface"})
    assert r.status_code == 200, r.text
    entry = client.app.state.tactilize.texture("corduroy")
    stroke = parse_stroke(rows, "<stroke>", entry.map.width_m, entry.map.height_m)
    tl = run_stroke(stroke, entry.map, Profile.preset("surface"), surface=entry.surface)
    plan = plan_events(tl.events, HJIF_TRANSIENT_S, tl.end_s)
    track = read_hjif(r.content)
    assert plan.transients and [round(t.t_s, 3) for t in track.taps] == [round(e.t_s, 3) for e in plan.transients]


def test_each_format_downloads_under_its_own_name(client):
    """One stroke exported in every format, and the stroke itself: no file overwrites another."""
    from tactilize.export import FORMATS

    names = []
    for fmt in FORMATS:
        r = client.post("/api/export/stroke", json={"texture": "corduroy", "format": fmt, "samples": _rows()})
        assert r.status_code == 200, (fmt, r.text)
        names.append(r.headers["content-disposition"].split('filename="')[1].rstrip('"'))
    assert "stroke-corduroy.csv" not in names  # the page's "Download stroke"
    assert len(set(names)) == len(names), names
    assert all(n.startswith("stroke-corduroy") for n in names)
    assert names[list(FORMATS).index("log")] == "stroke-corduroy-log.csv"
    assert names[list(FORMATS).index("android")] == "stroke-corduroy.android.json"


@pytest.mark.parametrize(
    "body, status, fault",
    [
        ({"texture": "corduroy", "format": "ahap", "samples": []}, 422, "empty"),
        ({"texture": "corduroy", "format": "ahap", "samples": [[0, 1, 1], [0, 2, 1]]}, 422, "times must increase"),
        ({"texture": "corduroy", "format": "ahap", "samples": [[0, 1, 1], [0.01, 9000, 1]]}, 422, "outside the picture"),
        ({"texture": "corduroy", "format": "mp3", "samples": _rows()}, 422, "unknown export format"),
        ({"texture": "nosuch", "format": "ahap", "samples": _rows()}, 404, "no texture"),
    ],
)
def test_bad_strokes_are_refused_in_one_line(client, body, status, fault):
    r = client.post("/api/export/stroke", json=body)
    assert r.status_code == status
    msg = r.json()["error"]
    assert fault in msg and "\n" not in msg


# ----------------------------------------------------------------- the page (Chromium)


@pytest.mark.browser
def test_download_and_export_the_last_stroke(browser, server, tmp_path):
    from test_browser import Pen, opened_page, pick, surface_box

    with opened_page(browser, server, accept_downloads=True) as page:
        pick(page, "corduroy")
        pen = Pen(page)
        box = surface_box(page)
        pen.stroke(box["x"] + 15, box["y"] + 40, 40.0 / (25.4 / 96), duration_s=0.4)
        pen.lift(pen.last_x, box["y"] + 40)
        with page.expect_download() as dl:
            page.get_by_test_id("stroke-download").click()
        text = open(dl.value.path()).read()
        rows = list(csv.reader(io.StringIO(text)))
        assert rows[0] == ["t_s", "x_mm", "y_mm", "pressure"] and len(rows) > 10
        t = [float(r[0]) for r in rows[1:]]
        assert t[0] == 0.0 and all(b > a for a, b in zip(t, t[1:]))
        assert float(rows[-1][1]) > float(rows[1][1])  # it moved right
        page.get_by_test_id("stroke-format").select_option("hjif")
        with page.expect_download() as dl:
            page.get_by_test_id("stroke-export-button").click()
        assert dl.value.suggested_filename == "stroke-corduroy.hjif"
        doc = json.loads(open(dl.value.path()).read())
        assert doc["timescale"] == 1000 and len(doc["perceptions"][0]["channels"]) == 2
        assert "exported" in page.get_by_test_id("stroke-export-status").text_content()


def _moves(pen, x0, y0, dx_px, n, interval_s=0.004):
    """Press at (x0, y0), ``n`` pen moves ``dx_px`` apart, ``interval_s`` apart on the
    events' own clock, then lift; returns the last x [CSS px]."""
    import time

    epoch0 = time.time()
    pen._send("mousePressed", x0, y0, 1, at_s=epoch0)
    x = x0
    for i in range(1, n + 1):
        x = x0 + dx_px * i
        pen._send("mouseMoved", x, y0, 1, at_s=epoch0 + i * interval_s)
        time.sleep(interval_s)
    pen.lift(x, y0)
    return x


def _download(page):
    with page.expect_download() as dl:
        page.get_by_test_id("stroke-download").click()
    rows = list(csv.reader(io.StringIO(open(dl.value.path()).read())))
    assert rows[0] == ["t_s", "x_mm", "y_mm", "pressure"]
    return dl.value.suggested_filename, [[float(v) for v in r[:3]] for r in rows[1:]]


@pytest.mark.browser
def test_the_stroke_download_records_every_copy_of_a_filled_surface(browser, server):
    """Filling the screen repeats the picture: a stroke on its second row, or across into its
    second copy, is recorded where it falls on the picture, and a stroke forgets the one before."""
    from test_browser import DEFAULT_MM_PER_PX, Pen, opened_page, pick, surface_box

    mm = DEFAULT_MM_PER_PX
    with opened_page(browser, server, accept_downloads=True, viewport={"width": 1280, "height": 1100}) as page:
        assert page.get_by_test_id("fill").is_checked()  # the default
        pick(page, "wood")
        pen = Pen(page)
        box = surface_box(page)
        # a stroke on wood, recorded
        _moves(pen, box["x"] + 10, box["y"] + 20, 1.0, 60)
        name, wood = _download(page)
        assert name == "stroke-wood.csv" and len(wood) > 30

        pick(page, "corduroy")
        box = surface_box(page)
        h_mm, w_mm = box["height"] * mm, box["width"] * mm
        vis = page.evaluate("window.tactilize.visible")
        assert vis["h"] * mm > 60.0, vis  # a second row is shown
        # Picked and not yet stroked: nothing of the wood stroke is offered.
        page.get_by_test_id("stroke-download").click()
        assert "stroke the picture first" in page.get_by_test_id("stroke-export-status").text_content()

        # the second row: y = 56 mm on a picture 50.8 mm tall
        y_px = box["y"] + 56.0 / mm
        _moves(pen, box["x"] + 10, y_px, 1.0, 100)
        name, rows = _download(page)
        assert name == "stroke-corduroy.csv"
        assert len(rows) >= 90, len(rows)  # the moves, not the wood stroke's samples
        ys = [r[2] for r in rows]
        assert all(abs(y - (56.0 - h_mm)) < 0.5 for y in ys), (min(ys), max(ys))
        assert all(b > a for a, b in zip([r[1] for r in rows], [r[1] for r in rows][1:]))

        # across the right edge into the second copy: 200 moves of 1 px from 30 px inside it
        x0 = box["x"] + box["width"] - 30
        _moves(pen, x0, box["y"] + 20, 1.0, 200)
        name, rows = _download(page)
        assert len(rows) >= 180, len(rows)
        xs = [r[1] for r in rows]
        assert all(0.0 <= x < w_mm for x in xs)
        wrapped = [i for i in range(1, len(xs)) if xs[i] < xs[i - 1]]
        assert len(wrapped) == 1, wrapped  # one crossing onto the copy, back at the picture's left edge
        assert xs[wrapped[0]] < 1.0 and xs[wrapped[0] - 1] > w_mm - 1.0
        assert xs[-1] == pytest.approx((170 * 1.0) * mm, abs=1.0)


from test_browser import browser, server  # noqa: E402,F401  (the fixtures: one server, one Chromium)
