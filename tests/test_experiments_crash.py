"""The server killed with SIGKILL in the middle of a session: nothing committed is lost or doubled.

A real uvicorn process on a free loopback port with an SQLite file; the
participant is a scripted HTTP + WebSocket client.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time

import httpx
from websockets.sync.client import connect

SERVER = (
    "import sys, uvicorn\n"
    "from tactilize.experiments.web import create_experiment_app\n"
    "uvicorn.run(create_experiment_app(sys.argv[1], sys.argv[2]), host='127.0.0.1', port=int(sys.argv[3]),"
    " log_level='warning')\n"
)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(db, protocol="alpha-law"):
    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-c", SERVER, protocol, str(db), str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise AssertionError(f"server died: {proc.stderr.read().decode()[-2000:]}")
        try:
            if httpx.get(f"{base}/experiment/api/protocol", timeout=1).status_code == 200:
                return proc, base, port
        except httpx.HTTPError:
            time.sleep(0.1)
    proc.kill()
    raise AssertionError("server did not start")


def _kill(proc):
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL


def test_sigkill_mid_session_then_resume(tmp_path):
    db = tmp_path / "crash.sqlite3"
    api = "/experiment/api"
    proc, base, port = _start(db)
    try:
        st = httpx.post(f"{base}{api}/sessions", json={"participant_id": "K1", "consent": True}).json()
        token = st["session"]
        httpx.post(f"{base}{api}/sessions/{token}/calibration", json={"mm_per_px": 0.25, "felt": True})
        given = {}
        for i in range(2):
            ratings = {"speed_match": 2 + i, "speed_difference": 6 - i}
            r = httpx.post(f"{base}{api}/sessions/{token}/answers", json={"trial": i, "ratings": ratings})
            assert r.status_code == 200 and r.json()["recorded"] == "recorded"
            given[i] = ratings
        with connect(f"ws://127.0.0.1:{port}/experiment/ws/{token}") as ws:
            ws.send(json.dumps({"type": "samples", "trial": 2, "image": "image3", "samples": [[k * 8.0, k * 0.5, 3.0, 0.4] for k in range(30)]}))
            assert json.loads(ws.recv(timeout=10))["logged"] == 30
            # Written = acknowledged: the ack follows the commit (the drive goes back before it).
            assert json.loads(ws.recv(timeout=30))["type"] == "ack"
            # The answer to trial 2 is in flight when the server dies: it may or may not
            # have been committed, but it must end up stored exactly once either way.
            in_flight = {"speed_match": 7, "speed_difference": 1}
            t = threading.Thread(target=lambda: _post_quietly(f"{base}{api}/sessions/{token}/answers",
                                                              {"trial": 2, "ratings": in_flight}))
            t.start()
            _kill(proc)
            t.join(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()

    proc, base, port = _start(db)
    try:
        st = httpx.get(f"{base}{api}/sessions/{token}").json()  # as the page resumes: by its session token
        assert st["session"] == token
        assert st["state"] == "trial" and st["trial"]["index"] in (2, 3)
        assert st["progress"]["done"] in (2, 3)
        # The client retries everything it is not sure of; the server takes each once.
        for i, ratings in given.items():
            r = httpx.post(f"{base}{api}/sessions/{token}/answers", json={"trial": i, "ratings": ratings})
            assert r.status_code == 200 and r.json()["recorded"] == "duplicate"
        r = httpx.post(f"{base}{api}/sessions/{token}/answers", json={"trial": 2, "ratings": in_flight})
        assert r.status_code == 200 and r.json()["recorded"] in ("recorded", "duplicate")
        given[2] = in_flight
        given[3] = {"speed_match": 4, "speed_difference": 4}
        r = httpx.post(f"{base}{api}/sessions/{token}/answers", json={"trial": 3, "ratings": given[3]})
        assert r.json()["state"] == "done"
        # A reused ID after the end: refused, and says the session is finished.
        again = httpx.post(f"{base}{api}/sessions", json={"participant_id": "K1", "consent": True})
        assert again.status_code == 409 and again.json()["finished"] is True
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=20)

    with sqlite3.connect(db) as con:
        rows = con.execute(
            'select t."index", a.question_id, a.rating from answers a join trials t on a.trial_id = t.id').fetchall()
        samples = con.execute("select count(*) from stroke_samples").fetchone()[0]
        sessions = con.execute("select count(*) from sessions").fetchone()[0]
    assert sessions == 1
    assert len(rows) == 4 * 2
    assert len({(i, q) for i, q, _ in rows}) == len(rows)  # each answer once
    assert {(i, q): r for i, q, r in rows} == {(i, q): r for i, d in given.items() for q, r in d.items()}
    assert samples == 30  # the stroke log written before the kill survived


def _post_quietly(url, body):
    try:
        httpx.post(url, json=body, timeout=5)
    except httpx.HTTPError:
        pass
