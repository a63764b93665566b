"""The stroke log loses nothing: late batches, resent batches, acknowledgements after the commit, SIGKILL.

The page's side of the contract (experiment.js: batches with ids, kept until
acknowledged, resent after a reconnect) is played here by a scripted client;
tests/test_experiments_reconnect.py plays it with the real page in Chromium.
"""

from __future__ import annotations

import contextlib
import json
import sqlite3
import threading
from collections import OrderedDict

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import event
from sqlalchemy.exc import IntegrityError

from tactilize.experiments.samples import SampleWriter, StrokeBatch, writer_for
from tactilize.experiments.store import Store
from tactilize.experiments.web import create_experiment_app

from _experiment_socket import API, open_session, pen_batch, until


def _rows(db, sql):
    with sqlite3.connect(db) as con:
        return con.execute(sql).fetchall()


@pytest.mark.timeout(180)  # a server that never acknowledges would keep the page waiting
def test_a_batch_arriving_after_the_answer_is_stored_under_its_trial(tmp_path):
    db = str(tmp_path / "late.sqlite3")
    with TestClient(create_experiment_app("alpha-law", db), base_url="http://127.0.0.1") as client:
        token, trial = open_session(client)
        image = trial["images"][0]["id"]
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            ws.send_json(pen_batch(0, image, "p-1"))
            kinds = [m["type"] for m in until(ws, "ack")]
            assert "drive" in kinds
            r = client.post(f"{API}/sessions/{token}/answers",
                            json={"trial": 0, "ratings": {"speed_match": 4, "speed_difference": 4}})
            assert r.json()["state"] == "trial" and r.json()["trial"]["index"] == 1
            # The last samples of trial 1 were on their way when Save went.
            ws.send_json(pen_batch(0, image, "p-2", start=5))
            late = until(ws, "ack")
            assert [m["type"] for m in late] == ["ack"]  # logged, not felt: no drive for an answered trial
            assert late[-1]["stored"] == "stored" and late[-1]["trial"] == 0
    rows = _rows(db, 'select t."index", s.image_id, s.t_s from stroke_samples s join trials t on s.trial_id = t.id')
    assert len(rows) == 10 and {(i, im) for i, im, _ in rows} == {(0, image)}
    assert sorted(round(t * 1e3, 6) for _, _, t in rows) == [k * 8.0 for k in range(10)]


@pytest.mark.timeout(180)  # a server that never acknowledges would keep the page waiting
def test_a_resent_batch_is_stored_once(tmp_path):
    db = str(tmp_path / "resent.sqlite3")
    with TestClient(create_experiment_app("alpha-law", db), base_url="http://127.0.0.1") as client:
        token, trial = open_session(client)
        image = trial["images"][0]["id"]
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            first = pen_batch(0, image, "p-7")
            ws.send_json(first)
            assert until(ws, "ack")[-1]["stored"] == "stored"
            # The page did not see that ack (the socket dropped) and sends it again, twice.
            ws.send_json(first)
            ws.send_json(first)
            assert until(ws, "ack")[-1]["stored"] == "duplicate"
            assert until(ws, "ack")[-1]["stored"] == "duplicate"
        # Over a new connection too (a reconnect after a server restart).
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            ws.send_json(first)
            assert until(ws, "ack")[-1]["stored"] == "duplicate"
    assert _rows(db, "select count(*) from stroke_samples") == [(5,)]
    assert _rows(db, "select batch_id, n_samples from stroke_batches") == [("p-7", 5)]


@pytest.mark.timeout(180)
def test_a_batch_near_the_float_limit_is_refused_and_the_session_lives(tmp_path):
    db = str(tmp_path / "huge.sqlite3")
    huge = 1.7e308
    with TestClient(create_experiment_app("alpha-law", db), base_url="http://127.0.0.1") as client:
        token, trial = open_session(client)
        image = trial["images"][0]["id"]
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            ws.send_json(pen_batch(0, image, "p-1"))
            assert until(ws, "ack")[-1]["stored"] == "stored"
            for k, rows in enumerate([[[48.0, huge, 3.0, 0.4], [56.0, -huge, 3.0, 0.4]],
                                      [[huge, 4.0, 3.0, 0.4], [-huge, 4.5, 3.0, 0.4]],
                                      [[64.0, 4.0, huge, 0.4], [72.0, 4.5, 3.0, 0.4]]]):
                ws.send_json({"type": "samples", "trial": 0, "image": image, "batch": f"h-{k}", "samples": rows})
                err = until(ws, "error")[-1]
                assert err["status"] == 422 and "must be within" in err["error"], err
            ws.send_json(pen_batch(0, image, "p-2", start=10))
            assert until(ws, "ack")[-1]["stored"] == "stored"
    assert _rows(db, "select batch_id from stroke_batches order by batch_id") == [("p-1",), ("p-2",)]


def test_the_unique_key_not_only_a_check_keeps_a_batch_single(tmp_path):
    db = str(tmp_path / "unique.sqlite3")
    with TestClient(create_experiment_app("alpha-law", db), base_url="http://127.0.0.1") as client:
        token, trial = open_session(client)
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            ws.send_json(pen_batch(0, trial["images"][0]["id"], "p-1"))
            until(ws, "ack")
    store = Store(db)
    with pytest.raises(IntegrityError):
        with store.Session.begin() as s:
            s.add(StrokeBatch(session_id=1, trial_id=1, batch_id="p-1", n_samples=5))
    # Two processes' writers racing on one batch: the loser's insert is refused and
    # it reports a duplicate (a writer that skips its check stands for the race).
    racer = SampleWriter(store)
    original = SampleWriter._write_once
    calls = []

    def unchecked(self, group):
        calls.append(1)
        if len(calls) == 1:  # the first attempt believes nothing is stored yet
            from sqlalchemy import insert

            with self.store.engine.begin() as conn:
                conn.execute(insert(StrokeBatch.__table__), [{"session_id": 1, "trial_id": 1, "batch_id": "p-1",
                                                               "n_samples": 5}])
        return original(self, group)

    SampleWriter._write_once = unchecked
    try:
        status = racer.submit(1, 1, "p-1", [{"image_id": "x", "t_s": 9.0, "x_m": 0.0, "y_m": 0.0, "pressure": None,
                                             "speed_m_s": 0.0, "pulse_frequency_hz": 1.0, "pulse_width_s": 1e-3,
                                             "amplitude": 1.0}]).result(timeout=60)
    finally:
        SampleWriter._write_once = original
    assert status == "duplicate" and len(calls) == 2
    assert _rows(db, "select count(*) from stroke_samples") == [(5,)]


@pytest.mark.timeout(180)  # a server that never acknowledges would keep the page waiting
def test_the_ack_waits_for_the_commit_and_the_drive_does_not(tmp_path):
    db = str(tmp_path / "ack.sqlite3")
    app = create_experiment_app("alpha-law", db)
    store = app.state.experiment_flow.store
    entered, release = threading.Event(), threading.Event()

    def hold_commit(conn):  # the writer's commits wait until the test releases them
        if threading.current_thread().name == SampleWriter.THREAD_NAME:
            entered.set()
            assert release.wait(60)

    event.listen(store.engine, "commit", hold_commit)
    with TestClient(app, base_url="http://127.0.0.1") as client:
        token, trial = open_session(client)
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            ws.send_json(pen_batch(0, trial["images"][0]["id"], "p-1"))
            drive = ws.receive_json()
            assert drive["type"] == "drive" and drive["batch"] == "p-1"  # the drive came back before the commit
            assert entered.wait(60)
            ws.send_json({"type": "ping"})
            assert [m["type"] for m in until(ws, "pong")] == ["pong"]  # no ack while the commit is held
            assert _rows(db, "select count(*) from stroke_samples") == [(0,)]
            release.set()
            ack = ws.receive_json()
            assert ack == {"type": "ack", "batch": "p-1", "trial": 0, "stored": "stored"}
            assert _rows(db, "select count(*) from stroke_samples") == [(5,)]


def test_samples_still_being_written_count_for_the_every_image_rule(tmp_path):
    db = str(tmp_path / "barrier.sqlite3")
    app = create_experiment_app("assessment", db)
    flow = app.state.experiment_flow
    with TestClient(app, base_url="http://127.0.0.1") as client:
        token, trial = open_session(client)
        handler = flow.stroke_handler(token)
        entered, release = threading.Event(), threading.Event()

        def hold_commit(conn):
            if threading.current_thread().name == SampleWriter.THREAD_NAME and not release.is_set():
                entered.set()
                assert release.wait(60)

        event.listen(flow.store.engine, "commit", hold_commit)
        futures = [handler.take(pen_batch(0, im["id"], f"p-{i}"))[1] for i, im in enumerate(trial["images"])]
        assert entered.wait(60)
        ratings = {q["id"]: q["scale_min"] for q in trial["questions"]}
        answer = threading.Thread(target=lambda: client.post(f"{API}/sessions/{token}/answers",
                                                             json={"trial": 0, "ratings": ratings}))
        answer.start()
        release.set()
        answer.join(60)
        assert all(f.result(timeout=60) == "stored" for f in futures)
    assert _rows(db, "select count(*) from answers") == [(len(ratings),)]


# ------------------------------------------------------------ SIGKILL mid-stroke


class Page:
    """experiment.js's side of the socket: batches kept until acknowledged, resent after a reconnect."""

    def __init__(self, port, token):
        self.url = f"ws://127.0.0.1:{port}/experiment/ws/{token}"
        self.ws = None
        self.stack = contextlib.ExitStack()
        self.pending: OrderedDict[str, str] = OrderedDict()
        self.acked: dict[str, str] = {}

    def connect(self):
        from websockets.sync.client import connect

        self.ws = self.stack.enter_context(connect(self.url, open_timeout=5))
        for text in self.pending.values():
            self.ws.send(text)

    def send(self, msg):
        self.pending[msg["batch"]] = json.dumps(msg)
        try:
            if self.ws is not None:
                self.ws.send(self.pending[msg["batch"]])
        except Exception:  # the server is gone: kept, sent after the reconnect
            self.ws = None

    def drain(self, timeout=0.0, until_empty=False):
        """Read what the server sent; with ``until_empty``, until every batch is acknowledged."""
        while self.ws is not None and (self.pending or not until_empty):
            try:
                msg = json.loads(self.ws.recv(timeout=timeout))
            except TimeoutError:
                return
            except Exception:
                self.ws = None
                return
            if msg["type"] == "ack":
                self.pending.pop(msg["batch"], None)
                self.acked[msg["batch"]] = msg["stored"]


@pytest.mark.timeout(180)  # a server that never acknowledges would keep the page waiting
def test_sigkill_mid_stroke_loses_nothing_the_page_kept(tmp_path):
    import httpx

    from test_experiments_crash import _kill, _start

    db = tmp_path / "kill.sqlite3"
    proc, base, port = _start(db)
    try:
        token, trial = open_session(httpx.Client(base_url=base))
        image = trial["images"][0]["id"]
        page = Page(port, token)
        page.connect()
        for b in range(40):
            page.send(pen_batch(0, image, f"p-{b}", start=5 * b))
            page.drain()
            if b == 19:  # mid-stroke: some batches committed, some in flight, some not yet sent
                _kill(proc)
        assert page.pending  # what the dead server never acknowledged, the page still holds
        proc, base, port = _start(db)
        page.url = f"ws://127.0.0.1:{port}/experiment/ws/{token}"
        page.connect()
        # The participant answers at once; the resent batches of that trial still go under it.
        r = httpx.post(f"{base}{API}/sessions/{token}/answers",
                       json={"trial": 0, "ratings": {"speed_match": 4, "speed_difference": 4}})
        assert r.status_code == 200
        page.drain(timeout=60, until_empty=True)
        assert not page.pending, f"{len(page.pending)} batches never acknowledged"
    finally:
        proc.kill()
        proc.wait(timeout=10)
    rows = _rows(db, 'select t."index", s.t_s from stroke_samples s join trials t on s.trial_id = t.id')
    assert sorted(round(t * 1e3, 6) for _, t in rows) == [k * 8.0 for k in range(200)]  # each sample once
    assert {i for i, _ in rows} == {0}
    assert _rows(db, "select count(*) from stroke_batches") == [(40,)]


def test_one_writer_per_store():
    class FakeStore:
        pass

    s = FakeStore()
    assert writer_for(s) is writer_for(s)
