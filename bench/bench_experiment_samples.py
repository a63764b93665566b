"""Benchmark of the experiment's stroke log: 20 participants at the page's rate, with SIGKILLs.

Runs the experiment app (``create_experiment_app`` on uvicorn, plus a bare
echo socket for the reference) in a subprocess on a loopback port, and plays
``--participants`` pages at once, each doing what experiment.js does:

- one batch every 30 ms (the page's flush period) of 4 samples (a 133 Hz pen's
  coalesced events), each stamped with its trial and image, with an id;
- every batch kept until its ``ack`` and resent, in order, after a reconnect
  (the socket reconnects from 250 ms, doubling up to 5 s, as the page does);
- each trial answered as soon as its stroke time is up, batches still in flight;
  the answer retried until the server takes it.

Runs, on SQLite (a file) and on PostgreSQL (``TACTILIZE_TEST_POSTGRES_URL``, in
a scratch schema dropped afterwards; skipped when unset):

1. no kill: drive latency back to the participant (batch sent -> its drive
   received), p50 / p99 (goal p99 < 50 ms), against the same clients on a bare
   echo socket of the same server measured in the same run, and the ratio;
2. ``--kills`` SIGKILLs of the server mid-stroke, each restarted on the same port.

Each run prints samples sent / stored / lost / duplicated / misattributed
(stored under another trial or image than the page stamped).

Usage::

    python bench/bench_experiment_samples.py               # ~3 minutes
    python bench/bench_experiment_samples.py --trials 2    # shorter
    python bench/bench_experiment_samples.py --db postgresql --kills 0   # one backend, latency only

No assertion on wall-clock time: figures and ratios are printed.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import random
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections import OrderedDict
from pathlib import Path

import httpx

FLUSH_S = 0.030         # experiment.js: setInterval(flush, FLUSH_MS = 30)
SAMPLES_PER_BATCH = 4   # a 133 Hz pen, coalesced events between two flushes
PROTOCOL = "alpha-law"

SERVER = r"""
import sys, uvicorn
from starlette.websockets import WebSocket
from tactilize.experiments.web import create_experiment_app
app = create_experiment_app(sys.argv[1], sys.argv[2])

@app.websocket("/echo")
async def echo(ws: WebSocket):
    await ws.accept()
    try:
        while True:
            msg = await ws.receive_json()
            await ws.send_json({"type": "drive", "batch": msg.get("batch")})
    except Exception:
        return

uvicorn.run(app, host="127.0.0.1", port=int(sys.argv[3]), log_level="warning")
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(db_url: str, port: int) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-W", "ignore", "-c", SERVER, PROTOCOL, db_url, str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise SystemExit(f"server exited with {proc.returncode}")
        try:
            if httpx.get(f"http://127.0.0.1:{port}/experiment/api/protocol", timeout=1).status_code == 200:
                return proc
        except httpx.HTTPError:
            time.sleep(0.05)
    proc.kill()
    raise SystemExit("server did not start")


def _pct(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(q / 100 * (len(xs) - 1))))] if xs else float("nan")


class Page:
    """One participant's page."""

    def __init__(self, code: str, base: str, ws_path: str):
        self.code, self.base, self.ws_path = code, base, ws_path
        self.pending: OrderedDict[str, str] = OrderedDict()
        self.sent_at: dict[str, float] = {}
        self.latency_s: list[float] = []
        self.expected: dict[float, tuple[int, str]] = {}  # t_ms -> (trial, image)
        self.ws = None
        self.seq = 0
        self.token = None
        self.stop = False

    async def _post(self, http, path, body):
        delay = 0.25
        while True:
            try:
                r = await http.post(self.base + path, json=body, timeout=10)
                if r.status_code < 500:
                    return r
            except httpx.HTTPError:
                pass
            await asyncio.sleep(delay)
            delay = min(5.0, delay * 2)

    async def connection(self):
        from websockets.asyncio.client import connect

        delay = 0.25
        url = self.base.replace("http", "ws", 1) + self.ws_path.format(token=self.token)
        while not self.stop:
            try:
                async with connect(url, open_timeout=5, max_queue=None) as ws:
                    delay = 0.25
                    self.ws = ws
                    for text in list(self.pending.values()):
                        await ws.send(text)
                    async for raw in ws:
                        msg = json.loads(raw)
                        if msg.get("type") == "drive":
                            if msg.get("batch") in self.sent_at:
                                self.latency_s.append(time.perf_counter() - self.sent_at.pop(msg["batch"]))
                            if self.ws_path == "/echo":  # the echo has no ack: its answer is one
                                self.pending.pop(msg["batch"], None)
                        elif msg.get("type") == "ack" or (msg.get("type") == "error" and msg.get("batch")
                                                           and not msg.get("retry")):
                            self.pending.pop(msg["batch"], None)
            except Exception:
                pass
            self.ws = None
            if self.stop:
                return
            await asyncio.sleep(delay)
            delay = min(5.0, delay * 2)

    async def send_batch(self, trial: int, image: str):
        self.seq += 1
        batch = f"{self.code}-{self.seq}"
        rows = []
        for _ in range(SAMPLES_PER_BATCH):
            t_ms = len(self.expected) * 7.5
            self.expected[t_ms] = (trial, image)
            rows.append([t_ms, 5.0 + (t_ms * 0.06) % 40, 20.0, 0.5])
        text = json.dumps({"type": "samples", "trial": trial, "image": image, "batch": batch, "samples": rows})
        self.pending[batch] = text
        if self.ws is not None:
            self.sent_at[batch] = time.perf_counter()
            try:
                await self.ws.send(text)
            except Exception:
                self.sent_at.pop(batch, None)

    async def run(self, stroke_s: float, trials: int | None, echo_s: float | None = None):
        async with httpx.AsyncClient() as http:
            if echo_s is None:
                r = await self._post(http, "/experiment/api/sessions", {"participant_id": self.code, "consent": True})
                if r.status_code == 409:  # registered before a kill cut the answer: the page's Resume
                    r = await self._post(http, "/experiment/api/resume", {"participant_id": self.code})
                self.token = r.json()["session"]
                st = (await self._post(http, f"/experiment/api/sessions/{self.token}/calibration",
                                       {"mm_per_px": 0.25, "felt": True})).json()
            conn = asyncio.create_task(self.connection())
            if echo_s is not None:
                await self._stroke(0, "echo", echo_s)
            else:
                done = 0
                while st.get("state") == "trial" and (trials is None or done < trials):
                    t = st["trial"]
                    await self._stroke(t["index"], t["images"], stroke_s)
                    ratings = {q["id"]: q["scale_min"] for q in t["questions"]}
                    # Save at once: the last batches are still on their way.
                    st = (await self._post(http, f"/experiment/api/sessions/{self.token}/answers",
                                           {"trial": t["index"], "ratings": ratings,
                                            "submission_id": f"{self.code}:{t['index']}"})).json()
                    done += 1
            deadline = time.monotonic() + 120
            while self.pending and time.monotonic() < deadline:
                await asyncio.sleep(0.05)
            self.stop = True
            if self.ws is not None:
                await self.ws.close()
            try:
                await asyncio.wait_for(conn, 10)
            except (asyncio.TimeoutError, asyncio.CancelledError):
                pass

    async def _stroke(self, trial: int, images, seconds: float):
        start = time.perf_counter()
        n = int(seconds / FLUSH_S)
        for k in range(n):
            image = images if isinstance(images, str) else images[(k * len(images)) // n]["id"]
            await self.send_batch(trial, image)
            await asyncio.sleep(max(0.0, start + (k + 1) * FLUSH_S - time.perf_counter()))


async def _kill_loop(state, kills: int, period_s: float):
    rng = random.Random(7)
    for _ in range(kills):
        await asyncio.sleep(period_s * rng.uniform(0.6, 1.4))
        os.kill(state["proc"].pid, signal.SIGKILL)
        state["proc"].wait()
        state["proc"] = await asyncio.to_thread(_start, state["db"], state["port"])


def _audit(db_url: str, pages: list[Page]) -> dict[str, int]:
    from sqlalchemy import create_engine, text

    engine = create_engine(db_url)
    q = text('select p.code, t."index", s.image_id, s.t_s from stroke_samples s join trials t on s.trial_id = t.id '
             "join sessions x on t.session_id = x.id join participants p on x.participant_id = p.id")
    with engine.connect() as conn:
        rows = conn.execute(q).all()
    engine.dispose()
    by = {p.code: p for p in pages}
    seen: dict[tuple[str, float], int] = {}
    mis = 0
    for code, idx, image, t_s in rows:
        page = by.get(code)
        if page is None:
            continue
        key = round(t_s * 1e3, 3)
        seen[(code, key)] = seen.get((code, key), 0) + 1
        if page.expected.get(key) != (idx, image):
            mis += 1
    sent = sum(len(p.expected) for p in pages)
    lost = sum(1 for p in pages for k in p.expected if (p.code, k) not in seen)
    dup = sum(n - 1 for n in seen.values() if n > 1)
    return {"sent": sent, "stored": sum(seen.values()), "lost": lost, "duplicated": dup, "misattributed": mis}


async def _run(db_url: str, label: str, n: int, kills: int, stroke_s: float, trials: int | None, echo: bool):
    port = _free_port()
    state = {"db": db_url, "port": port, "proc": await asyncio.to_thread(_start, db_url, port)}
    base = f"http://127.0.0.1:{port}"
    out: dict = {"db": label, "kills": kills}
    try:
        if echo:
            pages = [Page(f"E{i}", base, "/echo") for i in range(n)]
            await asyncio.gather(*(p.run(stroke_s, None, echo_s=stroke_s * 2) for p in pages))
            lat = [x for p in pages for x in p.latency_s]
            out["echo_ms"] = (1e3 * _pct(lat, 50), 1e3 * _pct(lat, 99), len(lat))
        tag = f"{label[:2]}{kills}{os.getpid() % 1000}"
        # Warm-up (lazy imports, first profile): one short participant, not counted.
        await Page(f"W{tag}", base, "/experiment/ws/{token}").run(0.3, 1)
        pages = [Page(f"B{tag}-{i:02d}", base, "/experiment/ws/{token}") for i in range(n)]
        t0 = time.perf_counter()
        jobs = [p.run(stroke_s, trials) for p in pages]
        if kills:
            jobs.append(_kill_loop(state, kills, stroke_s * (trials or 4) / (kills + 1)))
        await asyncio.gather(*jobs)
        out["seconds"] = time.perf_counter() - t0
        lat = [x for p in pages for x in p.latency_s]
        out["drive_ms"] = (1e3 * _pct(lat, 50), 1e3 * _pct(lat, 99), len(lat))
        out["unacked"] = sum(len(p.pending) for p in pages)
    finally:
        state["proc"].send_signal(signal.SIGTERM)
        try:
            state["proc"].wait(timeout=20)
        except subprocess.TimeoutExpired:
            state["proc"].kill()
    out.update(_audit(db_url, pages))
    return out


def _postgres_schema(url: str):
    from sqlalchemy import create_engine, text

    schema = f"bench_samples_{os.getpid()}"
    engine = create_engine(url)
    with engine.begin() as conn:
        conn.execute(text(f"create schema {schema}"))
    sep = "&" if "?" in url else "?"
    return f"{url}{sep}options=-csearch_path%3D{schema}", lambda: _drop(engine, schema)


def _drop(engine, schema):
    from sqlalchemy import text

    with engine.begin() as conn:
        conn.execute(text(f"drop schema {schema} cascade"))
    engine.dispose()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=20)
    ap.add_argument("--trials", type=int, default=4, help="trials per participant (alpha-law has 4)")
    ap.add_argument("--stroke-s", type=float, default=3.0, help="stroke time per trial, seconds")
    ap.add_argument("--kills", type=int, default=5)
    ap.add_argument("--db", choices=("both", "sqlite", "postgresql"), default="both",
                    help="which backend(s) to run (postgresql needs TACTILIZE_TEST_POSTGRES_URL)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    results = []
    with tempfile.TemporaryDirectory() as tmp:
        dbs = [("sqlite", f"sqlite:///{Path(tmp) / 'bench.sqlite3'}", None)] if args.db != "postgresql" else []
        pg = os.environ.get("TACTILIZE_TEST_POSTGRES_URL") if args.db != "sqlite" else None
        if pg:
            url, drop = _postgres_schema(pg)
            dbs.append(("postgresql", url, drop))
        try:
            for label, url, _ in dbs:
                for kills in sorted({0, args.kills}):  # --kills 0: the latency run alone
                    r = asyncio.run(_run(url, label, args.participants, kills, args.stroke_s, args.trials,
                                         echo=kills == 0))
                    results.append(r)
                    if not args.json:
                        _print(r, args.participants)
        finally:
            for _, _, drop in dbs:
                if drop:
                    drop()
    if not pg and args.db != "sqlite" and not args.json:
        print("postgresql: skipped (set TACTILIZE_TEST_POSTGRES_URL)")
    if args.json:
        print(json.dumps(results, indent=2))


def _print(r, n):
    head = f"{r['db']:<10} {n} participants, {r['kills']} SIGKILLs"
    print(f"{head}: samples sent {r['sent']}, stored {r['stored']}, lost {r['lost']}, duplicated {r['duplicated']}, "
          f"misattributed {r['misattributed']} ({r['unacked']} batches never acknowledged; {r['seconds']:.1f} s)")
    if r["kills"]:
        return
    d50, d99, nd = r["drive_ms"]
    line = f"{'':<10} drive latency p50 {d50:.1f} ms, p99 {d99:.1f} ms ({nd} batches)"
    if "echo_ms" in r:
        e50, e99, _ = r["echo_ms"]
        line += (f"; bare echo p50 {e50:.1f} ms, p99 {e99:.1f} ms; ratio p50 {d50 / e50:.1f}x, "
                 f"p99 {d99 / e99:.1f}x")
    print(line)


if __name__ == "__main__":
    main()
