"""What a lab runs into -- simulation beside real data, silent conditions,
paper-ready figures, error paths, backups, withdrawals, exports."""

from __future__ import annotations

import csv
import io
import json
import os
import sqlite3
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from tactilize.cli import main
from tactilize.experiments.flow import Flow, FlowError
from tactilize.experiments.protocols import (
    ProtocolError,
    load_protocol,
    protocol_from_toml,
)
from tactilize.experiments.simulate import simulate
from tactilize.experiments.store import Store

ENV = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in [os.path.join(os.path.dirname(__file__), "..", "src"),
                                                              os.environ.get("PYTHONPATH", "")] if p))


def _cli(*args):
    return CliRunner().invoke(main, ["experiment", *args])


def _one_line_exit_2(r):
    assert r.exit_code == 2, r.output
    assert r.output.count("\n") == 1 and r.output.startswith("tactilize: "), r.output
    assert "internal error" not in r.output and "Traceback" not in r.output


def _real_participant(flow, code, rating=5):
    state = flow.start(code, True)
    token = state["session"]
    state = flow.calibrate(token, {"mm_per_px": 0.25, "felt": True})
    handler = flow.stroke_handler(token)
    while state["state"] != "done":
        if state["state"] == "break":
            state = flow.end_break(token, state["next_trial"])
            continue
        t = state["trial"]
        handler.handle({"type": "samples", "trial": t["index"], "image": t["images"][0]["id"], "samples": [[0, 1, 1, 0.5], [20, 3, 1, 0.5]]})
        state = flow.submit(token, t["index"], {q["id"]: rating for q in t["questions"]})
    return token


# ------------------------------------------------------------ simulated vs real


def test_simulation_into_a_study_leaves_real_numbering_and_analysis_unchanged(tmp_path):
    proto = load_protocol("alpha-law")
    db = str(tmp_path / "study.sqlite3")
    flow = Flow(proto, Store(db))
    for i, code in enumerate(("P01", "P02")):
        _real_participant(flow, code, rating=3 + i)
    before = json.loads(_cli("analyze", "--db", db, "--json").output)
    assert simulate(proto, 3, seed=7, db_url=db)["started"] == 3
    _real_participant(flow, "P03", rating=6)  # registered after the simulation
    numbers = {r["participant"]: (r["participant_number"], r["simulated"]) for r in Store(db).sessions_overview()}
    assert numbers["P03"] == (3, False)  # not 6: the simulated ones do not take real square rows
    assert [numbers[f"SIM-7-00{i}"] for i in (1, 2, 3)] == [(1, True), (2, True), (3, True)]
    # P03's order is row 3 of the square, exactly as without the simulation.
    assert json.loads(Store(db).session_by_code("alpha-law", "P03").order_json) == [t.condition_id for t in proto.plan(3)]
    after = json.loads(_cli("analyze", "--db", db, "--json").output)
    assert after["protocols"]["alpha-law"]["n_participants"] == 3  # P01..P03 only
    with_sim = json.loads(_cli("analyze", "--db", db, "--json", "--include-simulated").output)
    assert with_sim["protocols"]["alpha-law"]["n_participants"] == 6
    # Removing P03 again from the picture: the two earlier real participants' statistics are untouched.
    from tactilize.experiments.analysis import analyze, tidy_answers

    df = tidy_answers(Store(db), include_simulated=False)
    again = analyze(df[df["participant"] != "P03"])
    assert again["protocols"]["alpha-law"]["questions"] == before["protocols"]["alpha-law"]["questions"]


def test_a_person_cannot_register_as_a_simulated_participant(tmp_path):
    flow = Flow(load_protocol("alpha-law"), Store(str(tmp_path / "s.db")))
    with pytest.raises(FlowError, match="reserved"):
        flow.start("SIM-1-001", True)


def test_simulate_needs_no_http_client(tmp_path):
    # httpx (fastapi.testclient's transport) is only in the test extra: block it.
    code = ("import sys, importlib.abc\n"
            "class Block(importlib.abc.MetaPathFinder):\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name.split('.')[0] == 'httpx' or name == 'fastapi.testclient':\n"
            "            raise ImportError('blocked: ' + name)\n"
            "sys.meta_path.insert(0, Block())\n"
            "from tactilize.cli import main\n"
            "main(['experiment', 'simulate', 'alpha-law', '--participants', '2', '--seed', '1', '--db', sys.argv[1]])\n")
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path / "p.db")], capture_output=True, text=True, env=ENV,
                       timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    assert "2 started" in r.stdout


# ------------------------------------------------------------ protocol check


def test_a_silent_condition_is_refused_with_one_line(tmp_path):
    text = load_protocol("g-law").text
    assert 'k2 = 30.0' in text
    bad = tmp_path / "silent.toml"
    bad.write_text(text.replace("k2 = 30.0", "k2 = -30.0", 1))
    with pytest.raises(ProtocolError, match="silent"):
        protocol_from_toml(bad.read_text(), str(bad))
    for cmd in (["run", str(bad), "--port", "0", "--db", str(tmp_path / "x.db")],
                ["simulate", str(bad), "--participants", "1", "--seed", "1", "--db", str(tmp_path / "x.db")]):
        r = _cli(*cmd)
        _one_line_exit_2(r)
        assert "condition H" in r.output and "silent" in r.output
    assert not (tmp_path / "x.db").exists()


# ------------------------------------------------------------ error paths


@pytest.fixture(scope="module")
def piloted(tmp_path_factory):
    db = str(tmp_path_factory.mktemp("pilot") / "pilot.sqlite3")
    simulate("alpha-law", 8, seed=2, db_url=db)
    return db


def test_error_paths_are_one_line_exit_2_and_create_nothing(tmp_path, piloted):
    (tmp_path / "afile").write_text("x")
    r = _cli("analyze", "--db", piloted, "--include-simulated", "--figures", str(tmp_path / "afile" / "figs"))
    _one_line_exit_2(r)
    assert "afile" in r.output

    typo = tmp_path / "typo.db"
    for cmd in (["status"], ["export"], ["analyze"], ["backup", str(tmp_path / "b.db")]):
        r = _cli(*cmd, "--db", str(typo))
        _one_line_exit_2(r)
        assert "no such database" in r.output
    assert not typo.exists() and not (tmp_path / "b.db").exists()

    out = tmp_path / "nosuch.csv"
    for cmd in (["export", "--protocol", "nosuch", "-o", str(out)], ["status", "--protocol", "nosuch"],
                ["analyze", "--protocol", "nosuch"]):
        r = _cli(*cmd, "--db", piloted)
        _one_line_exit_2(r)
        assert "nosuch" in r.output and "alpha-law" in r.output
    assert not out.exists()


def test_status_into_a_closed_pipe_exits_cleanly(piloted):
    proc = subprocess.Popen([sys.executable, "-m", "tactilize.cli", "experiment", "status", "--db", piloted],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=ENV)
    proc.stdout.readline()
    proc.stdout.close()  # what `| head -1` does
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 0, err
    assert "BrokenPipe" not in err and "Traceback" not in err and "internal error" not in err


def test_run_never_prints_the_database_password(tmp_path, monkeypatch):
    import tactilize.experiments.web as experiments_web
    import tactilize.web.serve as web_serve

    real = Store(str(tmp_path / "s.db"))
    real.url = "postgresql+psycopg://lab:s3cret-pw@db.example/study"
    monkeypatch.setattr(experiments_web, "Store", lambda url=None, **kw: real)  # the store `run` opens
    monkeypatch.setattr(web_serve, "serve", lambda *a, **k: k["echo"]("serving at http://127.0.0.1:1/"))
    r = _cli("run", "alpha-law", "--db", "ignored")
    assert r.exit_code == 0, r.output
    assert "s3cret" not in r.output and "db.example/study" in r.output


# ------------------------------------------------------------ figures


def _strong_effect_df(n=10):
    rng = np.random.default_rng(1)
    rows = []
    for p in range(n):
        for cond, mu in (("A", 6.5), ("B", 2.0), ("C", 6.0)):
            rows.append({"protocol": "alpha-law", "participant": f"P{p}", "condition": cond, "question": "speed_match",
                         "rating": int(np.clip(round(mu + rng.normal(0, 0.4)), 1, 7)), "seed": 1,
                         "protocol_sha256": "x" * 64, "simulated": False})
    return pd.DataFrame(rows)


def test_figures_are_paper_ready(tmp_path):
    from PIL import Image

    from tactilize.experiments.analysis import analyze
    from tactilize.experiments.figures import make_figures, significance_pairs

    df = _strong_effect_df()
    sig = significance_pairs(analyze(df), "alpha-law", "speed_match")
    assert {(a, b) for a, b, _ in sig} == {("A", "B"), ("B", "C")}  # A vs C is not different
    files = make_figures(df, tmp_path)["alpha-law"]
    svg = Path(files["svg"]).read_text("utf-8")
    assert 'id="sig:A:B"' in svg and 'id="sig:B:C"' in svg and "sig:A:C" not in svg
    assert "cf. paper" not in svg
    with Image.open(files["png"]) as im:
        assert round(im.info["dpi"][0]) == 300
    assert Path(files["pdf"]).read_bytes()[:4] == b"%PDF"
    assert "Fig. 14" in Path(files["caption"]).read_text("utf-8")


def test_figure_labels_come_from_the_protocol(tmp_path, piloted):
    from tactilize.experiments.figures import make_figures

    files = make_figures(Store(piloted), tmp_path, include_simulated=True)["alpha-law"]
    svg = Path(files["svg"]).read_text("utf-8")
    labels = [c.label for c in load_protocol("alpha-law").conditions]
    # The SVG keeps text as text; a long label is wrapped over lines, one <text> each.
    import html
    import re

    words = " ".join(html.unescape(t) for t in re.findall(r"<text[^>]*>([^<]*)", svg))
    words = " ".join(words.split())
    assert all(lab in words for lab in labels), (labels, words)
    assert load_protocol("alpha-law").title.split(":")[0] in words


# ------------------------------------------------------------ data out


def test_backup_while_a_session_writes_holds_every_committed_answer(tmp_path):
    db = str(tmp_path / "live.sqlite3")
    Store(db)
    done = threading.Event()
    failure = []

    def writer():
        try:
            simulate("alpha-law", 6, seed=4, db_url=db)
        except Exception as exc:  # noqa: BLE001 - any failure of the writer is reported below
            failure.append(exc)
        finally:
            done.set()

    th = threading.Thread(target=writer)
    th.start()
    k = 0
    while not done.is_set() or k < 2:
        with sqlite3.connect(db) as con:
            committed = con.execute("select count(*) from answers").fetchone()[0]
        target = tmp_path / f"backup-{k}.sqlite3"
        r = _cli("backup", str(target), "--db", db)
        assert r.exit_code == 0, r.output
        with sqlite3.connect(target) as con:
            assert con.execute("pragma integrity_check").fetchone()[0] == "ok"
            assert con.execute("select count(*) from answers").fetchone()[0] >= committed
        k += 1
    th.join()
    assert not failure
    r = _cli("backup", str(tmp_path / "backup-0.sqlite3"), "--db", db)
    _one_line_exit_2(r)  # never overwrites


def test_withdraw_deletes_one_participant_and_keeps_the_others_rows(tmp_path):
    db = str(tmp_path / "w.sqlite3")
    flow = Flow(load_protocol("alpha-law"), Store(db))
    for code in ("P01", "P02"):
        _real_participant(flow, code)
    r = _cli("withdraw", "alpha-law", "P01", "--db", db, "--yes")
    assert r.exit_code == 0, r.output
    store = Store(db)
    assert {r["participant"] for r in store.answer_rows()} == {"P02"}
    assert all(s["session"] != 1 for s in store.stroke_rows())
    _real_participant(flow, "P03")
    assert {r["participant"]: r["participant_number"] for r in store.sessions_overview()} == {"P02": 2, "P03": 3}
    _one_line_exit_2(_cli("withdraw", "alpha-law", "P01", "--db", db, "--yes"))


def test_exports_wide_parquet_full_hash_and_stroke_conditions(tmp_path, piloted):
    r = _cli("export", "--db", piloted, "--format", "wide")
    assert r.exit_code == 0, r.output
    wide = list(csv.DictReader(io.StringIO(r.output)))
    assert len(wide) == 8 and "B_speed_match" in wide[0]
    pq = tmp_path / "a.parquet"
    assert _cli("export", "--db", piloted, "--format", "parquet", "-o", str(pq)).exit_code == 0
    tidy = pd.read_parquet(pq)
    assert len(tidy) == 8 * 4 * 2 and len(tidy["protocol_sha256"].iloc[0]) == 64
    assert tidy["protocol_sha256"].iloc[0] == load_protocol("alpha-law").sha256
    strokes = list(csv.DictReader(io.StringIO(_cli("export", "--db", piloted, "--strokes").output)))
    assert {"condition", "image"} <= set(strokes[0]) and {s["condition"] for s in strokes} == {"A", "B", "C", "D"}


# ------------------------------------------------------------ participants


def test_assessment_rating_waits_until_every_image_is_stroked(tmp_path):
    proto = load_protocol("assessment")
    assert proto.require_every_image
    flow = Flow(proto, Store(str(tmp_path / "a.db")))
    token = flow.start("P01", True)["session"]
    state = flow.calibrate(token, {"mm_per_px": 0.25, "felt": True})
    t = state["trial"]
    assert t["require_every_image"] and len(t["images"]) == 6
    handler = flow.stroke_handler(token)
    ratings = {q["id"]: 4 for q in t["questions"]}
    for im in t["images"][:5]:
        handler.handle({"type": "samples", "trial": 0, "image": im["id"], "samples": [[0, 1, 1, 0.5], [20, 3, 1, 0.5]]})
    with pytest.raises(FlowError, match="stroke every picture") as exc:
        flow.submit(token, 0, ratings)
    assert exc.value.detail["unstroked"] == [t["images"][5]["id"]]
    assert flow.store.answer_rows() == []
    handler.handle({"type": "samples", "trial": 0, "image": t["images"][5]["id"], "samples": [[0, 1, 1, 0.5]]})
    assert flow.submit(token, 0, ratings)["recorded"] == "recorded"


def test_an_id_alone_does_not_resume_a_session_beyond_loopback(tmp_path):
    from fastapi.testclient import TestClient

    from tactilize.experiments.web import create_experiment_app

    app = create_experiment_app("alpha-law", str(tmp_path / "r.db"), admin_token="experimenter-secret")
    with TestClient(app, base_url="http://127.0.0.1") as client:  # its client address, "testclient", is not loopback
        token = client.post("/experiment/api/sessions", json={"participant_id": "P01", "consent": True}).json()["session"]
        assert len(token) >= 24  # unguessable: 18 random bytes
        r = client.post("/experiment/api/resume", json={"participant_id": "P01"})
        assert r.status_code == 401 and "token" in r.json()["error"]
        r = client.post("/experiment/api/resume", json={"participant_id": "P01"},
                        headers={"X-Tactilize-Token": "experimenter-secret"})
        assert r.status_code == 200 and r.json()["session"] == token
        assert client.get(f"/experiment/api/sessions/{token}").status_code == 200  # the page's own token works


def test_consent_file_next_to_the_protocol_and_free_text_comments(tmp_path):
    text = load_protocol("alpha-law").text.replace('name = "alpha-law"', 'name = "alpha-law"\nconsent_file = "consent.md"', 1)
    proto_path = tmp_path / "with-consent.toml"
    proto_path.write_text(text)
    with pytest.raises(ProtocolError, match="consent file"):
        load_protocol(str(proto_path))
    (tmp_path / "consent.md").write_text("You may stop at any time.\nYour data are kept under your ID only.\n")
    proto = load_protocol(str(proto_path))
    assert proto.consent.startswith("You may stop")
    db = str(tmp_path / "c.db")
    flow = Flow(proto, Store(db))
    token = flow.start("P01", True)["session"]
    prov = json.loads(flow.store.session_by_token(token).provenance_json)
    import hashlib

    assert prov["consent_sha256"] == hashlib.sha256(proto.consent.encode()).hexdigest()
    state = flow.calibrate(token, {"mm_per_px": 0.25, "felt": True})
    ratings = {q["id"]: 4 for q in state["trial"]["questions"]}
    with pytest.raises(FlowError, match="2000"):
        flow.submit(token, 0, ratings, comment="x" * 2001)
    flow.submit(token, 0, ratings, comment="  felt a buzz on image 2  ")
    flow.submit(token, 0, ratings, comment="again")  # a duplicate: nothing changes
    from tactilize.experiments.analysis import tidy_answers

    assert set(tidy_answers(Store(db))["comment"]) == {"felt a buzz on image 2"}


def test_an_excluded_participant_s_square_row_goes_to_the_next_one(tmp_path):
    proto = load_protocol("alpha-law")
    db = str(tmp_path / "x.sqlite3")
    flow = Flow(proto, Store(db))
    for code, rating in (("P01", 5), ("P02", 2), ("P03", 4)):
        _real_participant(flow, code, rating)
    r = _cli("exclude", "alpha-law", "P02", "--reason", "did not feel the pen", "--db", db)
    assert r.exit_code == 0 and "row 2" in r.output, r.output
    _one_line_exit_2(_cli("exclude", "alpha-law", "P02", "--db", db))
    _real_participant(flow, "P04", 6)
    store = Store(db)
    p04 = store.session_by_code("alpha-law", "P04")
    assert json.loads(p04.order_json) == [t.condition_id for t in proto.plan(2)]  # P02's row
    _real_participant(flow, "P05", 6)
    assert json.loads(store.session_by_code("alpha-law", "P05").order_json) == [t.condition_id for t in proto.plan(4)]
    from tactilize.experiments.analysis import analyze, tidy_answers

    df = tidy_answers(store)
    assert df[df["participant"] == "P02"]["excluded"].all() and set(df[df["participant"] == "P02"]["participant_number"]) == {2}
    assert analyze(store)["protocols"]["alpha-law"]["n_participants"] == 4
    status = {r["participant"]: (r["participant_number"], r["excluded"]) for r in store.sessions_overview()}
    assert status["P02"] == (2, True) and status["P04"] == (2, False)
    assert "(excluded)" in _cli("status", "--db", db).output


def test_optional_demographics_are_validated_stored_exported_and_withdrawn(tmp_path):
    text = load_protocol("alpha-law").text + (
        '\n[[demographics]]\nid = "age"\ntext = "Age"\nkind = "integer"\nmin = 18\nmax = 99\n'
        '\n[[demographics]]\nid = "handedness"\ntext = "Writing hand"\nkind = "choice"\noptions = ["left", "right"]\n')
    proto = protocol_from_toml(text, "demo.toml")
    assert [d.id for d in proto.demographics] == ["age", "handedness"]
    with pytest.raises(ProtocolError, match="kind"):
        protocol_from_toml(text.replace('kind = "integer"', 'kind = "text"'), "demo.toml")
    db = str(tmp_path / "d.db")
    flow = Flow(proto, Store(db))
    with pytest.raises(FlowError, match="18 .. 99"):
        flow.start("P01", True, demographics={"age": 7})
    with pytest.raises(FlowError, match="left, right"):
        flow.start("P01", True, demographics={"handedness": "up"})
    assert Store(db).sessions_overview() == []  # a refused form registers nobody
    flow.start("P01", True, demographics={"age": "34", "handedness": "left"})
    flow.start("P02", True, demographics={"age": "", "handedness": "right"})  # age declined
    from tactilize.experiments.demographics import all_answers
    from tactilize.experiments.labdata import withdraw

    assert all_answers(Store(db)) == {("alpha-law", "P01"): {"age": "34", "handedness": "left"},
                                      ("alpha-law", "P02"): {"handedness": "right"}}
    assert withdraw(Store(db), "alpha-law", "P01")["demographics"] == 2
    assert list(all_answers(Store(db))) == [("alpha-law", "P02")]


def test_wide_table_carries_demographics_beside_the_ratings():
    from tactilize.experiments.labdata import wide_table

    df = _strong_effect_df(3)
    wide = wide_table(df, {("alpha-law", "P0"): {"age": "30"}, ("alpha-law", "P2"): {"age": "41"}})
    assert list(wide.columns) == ["protocol", "participant", "age", "A_speed_match", "B_speed_match", "C_speed_match"]
    assert list(wide["age"]) == ["30", "", "41"]
    assert wide["B_speed_match"].tolist() == df[df["condition"] == "B"]["rating"].tolist()


def test_practice_trials_come_first_and_stay_out_of_the_analysis(tmp_path):
    proto = protocol_from_toml(load_protocol("alpha-law").text.replace("repetitions = ", "practice_trials = 2\nrepetitions = ", 1),
                               "practice.toml")
    plan = proto.plan(1)
    assert [t.repetition for t in plan[:3]] == [-1, -1, 0] and len(plan) == 2 + len(load_protocol("alpha-law").plan(1))
    db = str(tmp_path / "p.db")
    flow = Flow(proto, Store(db))
    state = flow.start("P01", True)
    state = flow.calibrate(state["session"], {"mm_per_px": 0.25, "felt": True})
    assert state["trial"]["practice"] is True
    _ = flow.submit(state["session"], 0, {q.id: 1 for q in proto.questions})
    from tactilize.experiments.analysis import export_answers, tidy_answers

    assert tidy_answers(Store(db)).empty  # the practice answer is not data
    rows = list(csv.DictReader(io.StringIO(export_answers(Store(db), "csv"))))
    assert [(r["trial"], r["repetition"]) for r in rows] == [("0", "-1")] * len(proto.questions)  # but is exported


def test_one_visit_runs_several_protocols_with_one_calibration(tmp_path):
    from tactilize.experiments.visit import Visit

    store = Store(str(tmp_path / "v.db"))
    visit = Visit([Flow(load_protocol("alpha-law"), store), Flow(load_protocol("assessment"), store)])
    state = visit.start("P01", True)
    assert state["visit"] == {"part": 1, "parts": 2, "protocols": ["alpha-law", "assessment"]}
    token = state["session"]
    state = visit.calibrate(token, {"mm_per_px": 0.3, "felt": True})
    seen = set()
    while state["state"] != "done":
        if state["state"] == "break":
            state = visit.end_break(state["session"], state["next_trial"])
            continue
        assert state["state"] == "trial"  # never a second calibration
        seen.add(state["visit"]["part"])
        tok, t = state["session"], state["trial"]
        handler = visit.stroke_handler(tok)
        for im in t["images"]:
            assert im["url"].endswith(f"?protocol={visit.flows[state['visit']['part'] - 1].design.name}")
            handler.handle({"type": "samples", "trial": t["index"], "image": im["id"], "samples": [[0, 1, 1, 0.5], [20, 3, 1, 0.5]]})
        state = visit.submit(tok, t["index"], {q["id"]: 4 for q in t["questions"]})
        assert state["recorded"] == "recorded"
    assert seen == {1, 2}
    overview = {r["protocol"]: r for r in store.sessions_overview()}
    assert set(overview) == {"alpha-law", "assessment"} and all(r["completed_at"] for r in overview.values())
    second = store.session_by_code("assessment", "P01")
    assert json.loads(second.calibration_json)["mm_per_px"] == 0.3
    assert visit.state(token)["state"] == "done" and visit.resume("P01")["state"] == "done"
    assert visit.image_png("image6", "assessment").startswith(b"\x89PNG")


def test_run_with_several_protocols_serves_one_visit(tmp_path, monkeypatch):
    import tactilize.web.serve as web_serve

    routers = []
    monkeypatch.setattr(web_serve, "serve", lambda *a, **k: routers.extend(k["extra_routers"]))
    r = _cli("run", "g-law", "h-law", "alpha-law", "assessment", "--db", str(tmp_path / "v.db"))
    assert r.exit_code == 0, r.output
    assert "one visit: g-law -> h-law -> alpha-law -> assessment" in r.output and len(routers) == 1


def test_the_protocol_check_plays_each_condition_on_the_simulated_wire(monkeypatch):
    from tactilize.experiments import checks

    # Every built-in condition is followed by the simulated paper wire (the real check).
    text = load_protocol("g-law").text
    played = []

    def fussy_wire(drive):  # a wire that cannot follow more than 250 Hz
        played.append(drive.pulse_frequency_hz)
        return drive.pulse_frequency_hz <= 250

    monkeypatch.setattr(checks, "_follows", fussy_wire)
    with pytest.raises(ProtocolError, match=r"^g.toml: condition C .* the wire would not follow its drive on image\d "
                                            r"at 60 mm/s \(300 Hz"):
        protocol_from_toml(text, "g.toml")
    assert played == pytest.approx([123.845, 247.69, 300.0], abs=0.5)  # A passes, B passes, C is refused
