"""A full disk during an experiment: an answer that cannot be stored is a one-line 503, the page keeps it and
sends it again, and once the store can write the same answer is stored exactly once (docs/safety.md, "The data")."""

from __future__ import annotations

import logging
import sqlite3
import threading

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import event

from tactilize.experiments.store import WAL_LIMIT_BYTES
from tactilize.experiments.web import create_experiment_app

from _experiment_socket import API, open_session, pen_batch, until


def _rows(db, sql):
    with sqlite3.connect(db) as con:
        return con.execute(sql).fetchall()


@pytest.mark.timeout(180)
def test_an_answer_on_a_full_disk_is_a_one_line_503_and_stored_once_when_space_is_back(tmp_path, caplog):
    db = str(tmp_path / "full.sqlite3")
    app = create_experiment_app("alpha-law", db)
    store = app.state.experiment_flow.store
    full = threading.Event()

    def disk_full(conn, cursor, statement, parameters, context, executemany):
        # What SQLite raises when a write needs a page the disk does not have.
        if full.is_set() and statement.lstrip().upper().startswith(("INSERT", "UPDATE")):
            raise sqlite3.OperationalError("database or disk is full")

    event.listen(store.engine, "before_cursor_execute", disk_full)
    caplog.set_level(logging.INFO)
    with TestClient(app, base_url="http://127.0.0.1", raise_server_exceptions=False) as client:
        token, trial = open_session(client)
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            ws.send_json(pen_batch(0, trial["images"][0]["id"], "p-1"))
            assert until(ws, "ack")[-1]["stored"] == "stored"
        answer = {"trial": 0, "ratings": {"speed_match": 4, "speed_difference": 3}, "submission_id": f"{token}:0"}
        full.set()
        for _ in range(3):  # the page sends it again while the disk is still full
            r = client.post(f"{API}/sessions/{token}/answers", json=answer)
            assert r.status_code == 503, r.text
            err = r.json()["error"]
            assert "database or disk is full" in err and "\n" not in err and r.json()["retry"] is True
        assert _rows(db, "select count(*) from answers") == [(0,)]
        full.clear()  # space is back
        r = client.post(f"{API}/sessions/{token}/answers", json=answer)
        assert r.status_code == 200 and r.json()["recorded"] == "recorded", r.text
        assert r.json()["trial"]["index"] == 1
        again = client.post(f"{API}/sessions/{token}/answers", json=answer)  # a response lost on the way
        assert again.status_code == 200 and again.json()["recorded"] == "duplicate"
    assert _rows(db, "select count(*) from answers") == [(2,)]
    # The write-ahead log that grew while the disk was full is cut back after the next checkpoint.
    with store.engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_size_limit").scalar() == WAL_LIMIT_BYTES
    assert _rows(db, 'select a.question_id, a.rating from answers a join trials t on a.trial_id = t.id '
                     'where t."index" = 0 order by a.question_id') == [("speed_difference", 3), ("speed_match", 4)]
    logged = [rec for rec in caplog.records if rec.levelno >= logging.WARNING]
    assert not any(rec.exc_info for rec in logged), [rec.getMessage() for rec in logged]
    assert not any("Exception in ASGI application" in rec.getMessage() for rec in logged)
    assert sum("not stored" in rec.getMessage() for rec in logged) == 3
