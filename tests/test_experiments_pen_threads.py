"""The drive back to the participant never waits behind requests blocked on the store.

Answers, starts and calibrations run in worker threads and wait on the database
(an answer waits for the writer's commit).  Pen messages used to run in the same
thread pool, so when every participant answered at once the drives queued behind
them.  Here the answers are held on the store (as a slow commit would) with
Starlette's pool no larger than their number: the pen socket still answers.
"""

from __future__ import annotations

import threading

import pytest
from fastapi.testclient import TestClient

from tactilize.experiments import flow as flow_mod
from tactilize.experiments.web import create_experiment_app

from _experiment_socket import API, open_session, pen_batch, until

RATINGS = {"speed_match": 4, "speed_difference": 4}


async def _pool_tokens(n):
    import anyio.to_thread

    anyio.to_thread.current_default_thread_limiter().total_tokens = n


@pytest.mark.timeout(180)
def test_the_drive_does_not_wait_behind_answers_held_on_the_store(tmp_path, monkeypatch):
    db = str(tmp_path / "held.sqlite3")
    with TestClient(create_experiment_app("alpha-law", db), base_url="http://127.0.0.1") as client:
        token, trial = open_session(client, "P1")
        others = [open_session(client, f"A{i}")[0] for i in range(3)]
        image = trial["images"][0]["id"]
        with client.websocket_connect(f"ws://127.0.0.1/experiment/ws/{token}") as ws:
            ws.send_json(pen_batch(0, image, "p-1", n=4))
            assert "drive" in [m["type"] for m in until(ws, "ack")]

            client.portal.call(_pool_tokens, len(others))
            release, entered = threading.Event(), threading.Semaphore(0)
            submit = flow_mod.Flow.submit

            def held(self, *a, **kw):  # an answer waiting on the database
                entered.release()
                release.wait(120)
                return submit(self, *a, **kw)

            monkeypatch.setattr(flow_mod.Flow, "submit", held)
            answers = [threading.Thread(target=client.post, args=(f"{API}/sessions/{t}/answers",),
                                        kwargs={"json": {"trial": 0, "ratings": RATINGS}}) for t in others]
            for th in answers:
                th.start()
            try:
                for _ in others:  # every answer holds its worker thread
                    assert entered.acquire(timeout=60)
                ws.send_json(pen_batch(0, image, "p-2", start=4, n=4))
                got: list = []
                reader = threading.Thread(target=lambda: got.append(until(ws, "drive")), daemon=True)
                reader.start()
                reader.join(60)  # the answers are still held: a drive queued behind them never comes
                answered_while_held = bool(got)
            finally:
                release.set()
                for th in answers:
                    th.join(60)
            assert answered_while_held
            assert got[0][-1]["batch"] == "p-2"
