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
    """With the surface profile the route exports the texture's bumps (issue 26), as the library does offline."""
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


from test_browser import browser, server  # noqa: E402,F401  (the fixtures: one server, one Chromium)
