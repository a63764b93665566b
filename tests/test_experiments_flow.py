"""The participant flow through its HTTP and WebSocket interface (in-process ASGI client)."""

from __future__ import annotations

import json
import sqlite3
import warnings

import pytest

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from tactilize.experiments.protocols import load_protocol
from tactilize.experiments.store import Store
from tactilize.experiments.web import create_experiment_app

API = "/experiment/api"


def _client(tmp_path, protocol="assessment", token="lab-token"):
    db = tmp_path / "exp.sqlite3"
    app = create_experiment_app(protocol, str(db), admin_token=token)
    return TestClient(app, base_url="http://127.0.0.1"), db


def _rows(db, sql):
    with sqlite3.connect(db) as con:
        return con.execute(sql).fetchall()


def test_scripted_participant_completes_the_assessment(tmp_path):
    client, db = _client(tmp_path)
    with client:
        page = client.get("/experiment/")
        assert page.status_code == 200 and "experiment.js" in page.text
        assert client.get("/experiment/static/experiment.js").status_code == 200
        info = client.get(f"{API}/protocol").json()
        assert [q["id"] for q in info["questions"]] == ["accordance", "difference", "velocity", "comfort"]
        assert "conditions" not in info  # the participant is blind to the condition

        st = client.post(f"{API}/sessions", json={"participant_id": "P01", "consent": True}).json()
        assert st["state"] == "calibration" and st["progress"] == {"done": 0, "total": 1}
        token = st["session"]
        st = client.post(f"{API}/sessions/{token}/calibration", json={"card_width_px": 323.5, "felt": True}).json()
        assert st["state"] == "trial"
        assert st["calibration"]["mm_per_px"] == pytest.approx(85.60 / 323.5)
        trial = st["trial"]
        assert sorted(im["id"] for im in trial["images"]) == [f"image{i}" for i in range(1, 7)]
        png = client.get(f"{API}/{trial['images'][0]['url']}")
        assert png.status_code == 200 and png.content[:8] == b"\x89PNG\r\n\x1a\n"
        # The page reserves the picture's box from these before it loads: they are the PNG's own.
        import io

        from PIL import Image

        im0 = trial["images"][0]
        assert Image.open(io.BytesIO(png.content)).size == (im0["width_px"], im0["height_px"])
        assert (im0["width_mm"], im0["height_mm"]) == pytest.approx((im0["width_px"] * 0.1, im0["height_px"] * 0.1))

        drives = {}
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            for im in trial["images"]:
                # 60 mm/s along x, 5 ms apart: the sigmoid's centre.
                ws.send_text(json.dumps({"type": "samples", "trial": 0, "image": im["id"],
                                         "samples": [[k * 5.0, k * 0.3, 10.0, 0.5] for k in range(20)]}))
                msg = ws.receive_json()
                while msg["type"] == "ack":  # the previous batch's, once committed
                    msg = ws.receive_json()
                assert msg["type"] == "drive" and msg["logged"] == 20
                assert msg["speed_mm_s"] == pytest.approx(60.0, rel=0.02)
                drives[im["id"]] = msg["drive"]
            ws.send_text(json.dumps({"type": "samples", "trial": 5, "image": "image1", "samples": [[0, 0, 0]]}))
            msg = ws.receive_json()
            while msg["type"] == "ack":
                msg = ws.receive_json()
            assert msg["type"] == "error"
        # The paper's laws: image 6 (finest, weakest) gets the narrowest pulses.
        assert min(drives, key=lambda i: drives[i]["pulse_width_s"]) == "image6"
        assert all(d["pulse_frequency_hz"] <= 300.0 for d in drives.values())

        ratings = {"accordance": 5, "difference": 6, "velocity": 4, "comfort": 7}
        done = client.post(f"{API}/sessions/{token}/answers",
                           json={"trial": 0, "ratings": ratings, "response_time_s": 12.5}).json()
        assert done["state"] == "done" and done["recorded"] == "recorded"
        assert done["progress"] == {"done": 1, "total": 1}

        csv = client.get(f"{API}/admin/export.csv?token=lab-token").text.strip().splitlines()
        header = csv[0].split(",")
        for col in ("participant", "session", "trial", "condition", "image", "question", "rating",
                    "answered_at", "trial_started_at", "seed", "protocol_sha256", "tactilize_version"):
            assert col in header
        assert len(csv) == 1 + 4
        got = {r.split(",")[header.index("question")]: int(r.split(",")[header.index("rating")]) for r in csv[1:]}
        assert got == ratings
    assert _rows(db, "select count(*) from stroke_samples")[0][0] == 6 * 20
    assert _rows(db, "select count(*) from answers")[0][0] == 4
    assert _rows(db, "select completed_at is not null from sessions")[0][0] == 1


def test_bad_input_is_refused_and_leaves_the_data_intact(tmp_path):
    client, db = _client(tmp_path, "alpha-law")
    with client:
        assert client.post(f"{API}/sessions", json={"participant_id": "P01", "consent": False}).status_code == 422
        bad_id = client.post(f"{API}/sessions", json={"participant_id": "../etc", "consent": True})
        assert bad_id.status_code == 422 and "participant_id" == bad_id.json()["source"]
        assert client.post(f"{API}/sessions", content=b"{not json", headers={"content-type": "application/json"}
                           ).status_code == 400
        unknown = client.post(f"{API}/resume", json={"participant_id": "P99", "token": "lab-token"})
        assert unknown.status_code == 404 and "not registered" in unknown.json()["error"]
        assert client.get(f"{API}/sessions/nonsense").status_code == 404

        token = client.post(f"{API}/sessions", json={"participant_id": "P01", "consent": True}).json()["session"]
        reused = client.post(f"{API}/sessions", json={"participant_id": "P01", "consent": True})
        assert reused.status_code == 409 and "already registered" in reused.json()["error"]

        good = {"speed_match": 5, "speed_difference": 3}
        # Answers before the calibration check: refused.
        assert client.post(f"{API}/sessions/{token}/answers", json={"trial": 0, "ratings": good}).status_code == 409
        for bad in ({"card_width_px": 3, "felt": True}, {"card_width_px": 320, "felt": False}, {"mm_per_px": "x"}):
            assert client.post(f"{API}/sessions/{token}/calibration", json=bad).status_code == 422
        first_cal = client.post(f"{API}/sessions/{token}/calibration", json={"mm_per_px": 0.25, "felt": True})
        assert first_cal.json()["recorded"] == "recorded"
        again_cal = client.post(f"{API}/sessions/{token}/calibration", json={"mm_per_px": 0.25, "felt": True})
        assert again_cal.status_code == 200 and again_cal.json()["recorded"] == "duplicate"
        # The scale is never replaced once recorded (earlier strokes were converted with it).
        assert client.post(f"{API}/sessions/{token}/calibration", json={"mm_per_px": 0.3, "felt": True}
                           ).status_code == 409

        for ratings in ({"speed_match": 8, "speed_difference": 3}, {"speed_match": 0, "speed_difference": 3},
                        {"speed_match": 4.5, "speed_difference": 3}, {"speed_match": True, "speed_difference": 3},
                        {"speed_match": 4}, {"speed_match": 4, "speed_difference": 3, "extra": 1}, [4, 3]):
            r = client.post(f"{API}/sessions/{token}/answers", json={"trial": 0, "ratings": ratings})
            assert r.status_code == 422, ratings
        # A stale page submitting a trial that is not open.
        stale = client.post(f"{API}/sessions/{token}/answers", json={"trial": 2, "ratings": good})
        assert stale.status_code == 409 and stale.json()["current_trial"] == 0
        assert _rows(db, "select count(*) from answers")[0][0] == 0

        first = client.post(f"{API}/sessions/{token}/answers", json={"trial": 0, "ratings": good})
        assert first.json()["recorded"] == "recorded"
        # A double click: same answers again, acknowledged, stored once.
        again = client.post(f"{API}/sessions/{token}/answers", json={"trial": 0, "ratings": good})
        assert again.status_code == 200 and again.json()["recorded"] == "duplicate"
        # A stale page trying to change an answer: refused, never overwritten.
        change = client.post(f"{API}/sessions/{token}/answers",
                             json={"trial": 0, "ratings": {"speed_match": 1, "speed_difference": 1}})
        assert change.status_code == 409 and "never overwritten" in change.json()["error"]
        # Strokes for a trial the session has not reached are refused (no page has shown it);
        # late ones for an answered trial are logged under it (tests/test_experiments_samples.py).
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            ws.send_json({"type": "samples", "trial": 3, "image": "image1", "batch": "b1", "samples": [[0, 1, 1, None], [5, 2, 1, None]]})
            err = ws.receive_json()
            assert err["type"] == "error" and err["current_trial"] == 1 and err["batch"] == "b1"
            ws.send_bytes(b"\xff not json")
            assert ws.receive_json()["type"] == "error"  # a broken message does not end the connection
            ws.send_json({"type": "lift"})
            assert ws.receive_json()["type"] == "lifted"
    assert _rows(db, "select question_id, rating from answers order by question_id") == [
        ("speed_difference", 3), ("speed_match", 5)]
    assert _rows(db, "select count(*) from stroke_samples")[0][0] == 0


def test_breaks_and_resume_by_participant_id(tmp_path):
    client, db = _client(tmp_path, "h-law")  # 8 trials, a break every 4
    with client:
        token = client.post(f"{API}/sessions", json={"participant_id": "R1", "consent": True}).json()["session"]
        client.post(f"{API}/sessions/{token}/calibration", json={"mm_per_px": 0.25, "felt": True})
        for i in range(4):
            st = client.post(f"{API}/sessions/{token}/answers", json={"trial": i, "ratings": {"comfort": 1 + i}}).json()
        assert st["state"] == "break" and st["next_trial"] == 4
        # A break must be taken: answering through it is refused.
        assert client.post(f"{API}/sessions/{token}/answers", json={"trial": 4, "ratings": {"comfort": 2}}
                           ).status_code == 409
        # An ID alone opens no session, on loopback neither (a rebinding page is "loopback");
        # the experimenter's token does.
        assert client.post(f"{API}/resume", json={"participant_id": "R1"}).status_code == 401
        resumed = client.post(f"{API}/resume", json={"participant_id": "R1", "token": "lab-token"}).json()
        assert resumed["session"] == token and resumed["state"] == "break"
        st = client.post(f"{API}/sessions/{token}/break", json={"trial": 4}).json()
        assert st["state"] == "trial" and st["trial"]["index"] == 4
        assert st["progress"] == {"done": 4, "total": 8}
    order = [r[0] for r in _rows(db, "select condition_id from trials order by \"index\"")]
    assert order == load_protocol("h-law").condition_order(1)


def test_experimenter_endpoints_need_the_token_even_on_loopback(tmp_path):
    client, _ = _client(tmp_path, "alpha-law", token="s3cret")
    with client:
        assert client.get(f"{API}/admin/sessions").status_code == 401
        assert client.get(f"{API}/admin/export.csv?token=wrong").status_code == 401
        assert client.get(f"{API}/admin/export.csv?token=s3cret").status_code == 200
        ok = client.get(f"{API}/admin/sessions", headers={"Authorization": "Bearer s3cret"})
        assert ok.status_code == 200 and ok.json()["protocol"]["name"] == "alpha-law"
        # The participant side needs none.
        assert client.get(f"{API}/protocol").status_code == 200
    (tmp_path / "open").mkdir()
    # No token given: one is made (a page on another site reaches loopback too).
    open_client, _ = _client(tmp_path / "open", "alpha-law", token=None)
    with open_client:
        assert open_client.get(f"{API}/admin/sessions").status_code == 401
        made = open_client.app.state.experiment_flow.admin_token
        assert len(made) >= 16
        assert open_client.get(f"{API}/admin/sessions", headers={"X-Tactilize-Token": made}).status_code == 200


def test_run_beyond_loopback_forces_and_prints_a_token(tmp_path, monkeypatch):
    from fastapi import FastAPI

    import tactilize.web.serve as pen_serve
    from tactilize.experiments import web

    assert web.is_loopback("127.0.0.1") and web.is_loopback("::1") and web.is_loopback("localhost")
    assert not web.is_loopback("0.0.0.0") and not web.is_loopback("192.168.1.4")
    captured = {}

    def fake_serve(host, port, output, profile, open_browser, *, extra_routers=(), echo=print, warn=print, **kw):
        # Stands in for the pen app's server: no socket is opened in this test.
        captured.update(host=host, routers=list(extra_routers))
        echo(f"tactilize: serving the tactile pen at http://{host}:4321/ (output simulated, profile paper)")

    monkeypatch.setattr(pen_serve, "serve", fake_serve)
    lines = []
    web.serve_flow("alpha-law", str(tmp_path / "t.sqlite3"), host="192.0.2.7", port=4321, echo=lines.append)
    admin_line = next(line for line in lines if "experimenter" in line)
    token = admin_line.split("token=")[1]
    assert len(token) >= 16 and "http://192.0.2.7:4321/experiment/admin" in admin_line
    app = FastAPI()
    for router in captured["routers"]:
        app.include_router(router)
    with TestClient(app, base_url="http://127.0.0.1") as client:
        assert client.get(f"{API}/admin/sessions").status_code == 401
        assert client.get(f"{API}/admin/sessions", headers={"X-Tactilize-Token": token}).status_code == 200
    # On loopback too: DNS rebinding makes any web site a loopback client.
    lines.clear()
    web.serve_flow("alpha-law", str(tmp_path / "t.sqlite3"), host="127.0.0.1", port=4321, echo=lines.append)
    assert any("token=" in line for line in lines)


def test_an_empty_host_binds_every_interface_so_a_token_is_forced(tmp_path, monkeypatch):
    # The experiments' own is_loopback called "" loopback: no token on a server
    # that the standalone path (uvicorn) binds to every interface.
    import tactilize.web.serve as pen_serve
    from tactilize.experiments import web

    monkeypatch.setattr(pen_serve, "serve", lambda *a, echo=print, **kw: echo("tactilize: serving at http://0.0.0.0:4321/"))
    lines = []
    web.serve_flow("alpha-law", str(tmp_path / "t.sqlite3"), host="", port=4321, echo=lines.append)
    assert any("token=" in line for line in lines)


def test_simulation_is_resumable_and_never_duplicates(tmp_path):
    from tactilize.experiments.simulate import simulate

    db = str(tmp_path / "sim.sqlite3")
    first = simulate("alpha-law", 3, seed=11, db_url=db, max_trials=6)
    assert first["trials_submitted"] == 6 and first["started"] == 2
    second = simulate("alpha-law", 3, seed=11, db_url=db)
    assert second["resumed"] == 1 and second["skipped"] == 1 and second["started"] == 1
    assert second["trials_submitted"] == 12 - 6
    rows = Store(db).answer_rows()
    assert len(rows) == 3 * 4 * 2
    assert len({(r["participant"], r["trial"], r["question"]) for r in rows}) == len(rows)
    assert all(r["simulated"] for r in rows) and {r["seed"] for r in rows} == {1003}
    # Same seed from scratch gives the same ratings: the interruption changed nothing.
    fresh = str(tmp_path / "fresh.sqlite3")
    simulate("alpha-law", 3, seed=11, db_url=fresh)
    key = lambda r: (r["participant"], r["trial"], r["question"], r["rating"])  # noqa: E731
    assert sorted(map(key, Store(fresh).answer_rows())) == sorted(map(key, rows))
    assert "simulation:alpha-law:11" in Store(db).meta()


def rate_every_trial(client, proto, participant, rating_of, scales):
    """One participant through every trial of ``proto`` (order 1), giving each
    trial ``rating_of(profile)`` on every one of ``scales``."""
    with client:
        token = client.post(f"{API}/sessions", json={"participant_id": participant, "consent": True}).json()["session"]
        client.post(f"{API}/sessions/{token}/calibration", json={"mm_per_px": 0.25, "felt": True})
        for i, cid in enumerate(proto.condition_order(1)):
            r = rating_of(proto.profile(cid))
            client.post(f"{API}/sessions/{token}/answers", json={"trial": i, "ratings": {k: r for k in scales}})


def test_personal_calibration_profile_is_usable(tmp_path):
    from tactilize.experiments.calibration import fit_personal_profile
    from tactilize.mapping import Profile

    db = str(tmp_path / "cal.sqlite3")
    client = TestClient(create_experiment_app("alpha-law", db), base_url="http://127.0.0.1")
    proto = load_protocol("alpha-law")
    # This person likes the steep sigmoid (k5 = 0.1) best, gentler and steeper less.
    liking = {0.02: 2, 0.05: 4, 0.1: 7, 0.2: 5}
    rate_every_trial(client, proto, "ME", lambda p: liking[p.speed.slope_per_mm_s], ("speed_match", "speed_difference"))
    prof, report = fit_personal_profile(Store(db), "ME")
    slope = prof.speed.slope_per_mm_s
    assert 0.05 < slope < 0.2 and report["fits"][0]["role"] == "speed"
    out = tmp_path / "me.toml"
    prof.save(out)
    again = Profile.load(out)
    assert again.speed.slope_per_mm_s == pytest.approx(slope)
    assert again.frequency == Profile.preset("paper").frequency  # untouched laws stay the paper's
    assert "ME" in again.description and "alpha-law" in again.description


def test_refinement_round_supersedes_the_first_fit(tmp_path):
    from tactilize.experiments.calibration import fit_personal_profile, refinement_protocol
    from tactilize.experiments.protocols import protocol_from_toml
    from tactilize.experiments.simulate import simulate

    db = str(tmp_path / "refine.sqlite3")
    simulate("alpha-law", 1, seed=4, db_url=db)
    store = Store(db)
    first, rep1 = fit_personal_profile(store, "SIM-4-001")
    k5 = first.speed.slope_per_mm_s
    text = refinement_protocol(store, "SIM-4-001", "speed", span_octaves=0.5, steps=5, repetitions=2)
    proto = protocol_from_toml(text)
    grid = sorted(proto.profile(c.id).speed.slope_per_mm_s for c in proto.conditions)
    assert grid == pytest.approx([k5 * 2**x for x in (-0.5, -0.25, 0, 0.25, 0.5)])
    assert len(proto.plan(1)) == 10 and "SIM-4-001" in text
    path = tmp_path / "refine.toml"
    path.write_text(text)
    # The same synthetic person (same seed and index) takes the refinement round.
    simulate(str(path), 1, seed=4, db_url=db)
    final, rep2 = fit_personal_profile(store, "SIM-4-001")
    fits = {(f["protocol"], f["superseded"]) for f in rep2["fits"]}
    assert ("alpha-law", True) in fits and (proto.name, False) in fits
    assert grid[0] - 1e-12 <= final.speed.slope_per_mm_s <= grid[-1] + 1e-12
    assert proto.name in final.description and "alpha-law (" not in final.description


@pytest.mark.skipif(not __import__("os").environ.get("TACTILIZE_TEST_POSTGRES_URL"),
                    reason="set TACTILIZE_TEST_POSTGRES_URL to a scratch PostgreSQL database")
def test_postgresql_store_takes_each_answer_once():
    import os
    import uuid

    from tactilize.experiments.simulate import simulate

    url = os.environ["TACTILIZE_TEST_POSTGRES_URL"]
    seed = uuid.uuid4().int % 10**6  # fresh participant IDs in a shared scratch database
    simulate("alpha-law", 2, seed=seed, db_url=url, max_trials=3)
    simulate("alpha-law", 2, seed=seed, db_url=url)
    rows = [r for r in Store(url).answer_rows("alpha-law") if r["participant"].startswith(f"SIM-{seed}-")]
    assert len(rows) == 2 * 4 * 2
    assert len({(r["participant"], r["trial"], r["question"]) for r in rows}) == len(rows)


def test_personal_calibration_fits_the_perceptual_profile(tmp_path):
    from tactilize.experiments.calibration import fit_personal_profile
    from tactilize.mapping import Profile

    db = str(tmp_path / "perc.sqlite3")
    client = TestClient(create_experiment_app("perceptual-law", db), base_url="http://127.0.0.1")
    proto = load_protocol("perceptual-law")
    # This person likes the textures a little more compressed than the preset (k = 0.7).
    liking = {0.6: 4, 0.7: 7, 0.836: 5, 0.95: 3, 1.1: 2}
    rate_every_trial(client, proto, "PK", lambda p: liking[p.frequency.exponent], ("match", "difference"))
    prof, report = fit_personal_profile(Store(db), "PK")
    assert report["base"] == "perceptual"  # the protocol's base, not the paper's
    k = prof.frequency.exponent
    assert 0.6 < k < 0.836 and report["fits"][0]["role"] == "frequency"
    assert prof.frequency.kind == "power"
    perceptual = Profile.preset("perceptual")
    assert prof.speed == perceptual.speed and prof.regularity == perceptual.regularity
