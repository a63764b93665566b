"""Benchmark of the pen server: latency and a sustained 1 kHz pen stream.

Runs ``tactilize serve`` (default output: the simulated wire) in a subprocess on
a free loopback port and measures

1. server-side latency: from a pen batch's arrival at the WebSocket endpoint
   to its drive handed to the socket, as the server records it (``/api/stats``),
   p50 / p99 (goal: p99 < 1 ms);
2. the WebSocket round trip on loopback (send a batch, receive its drive),
   p50 / p99 (goal: p99 < 5 ms), against a reference measured in the same run:
   a bare echo WebSocket on the same stack (Starlette on uvicorn), and the ratio;
3. 1,000 pen samples per second sustained for ``--seconds`` (60 by default),
   one sample per message (the harshest framing a page could choose), with the
   server's resident memory sampled along the way (flat memory: end vs start
   after warm-up).

Usage::

    python bench/bench_web.py                 # full run, ~75 s
    python bench/bench_web.py --seconds 10    # shorter sustained phase
    python bench/bench_web.py --json          # one JSON document

No assertion on wall-clock time: figures and ratios are printed.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import statistics
import subprocess
import sys
import threading
import time

import httpx
import psutil
from websockets.sync.client import connect

MM_PER_PX = 25.4 / 96


def pct(values, p):
    v = sorted(values)
    if not v:
        return math.nan
    return v[min(len(v) - 1, int(p / 100 * len(v)))]


def start(cmd):
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
    if not m:
        proc.kill()
        raise SystemExit(f"server did not start: {line!r} {proc.stderr.read()[-2000:]}")
    return proc, int(m.group(1))


def stop(proc):
    proc.terminate()
    try:
        proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()


# ----------------------------------------------------------------- reference echo server


# The floor of bench_page.py: a page that does nothing but send each raw pen
# update's own timeStamp to the echo and note when it comes back [ms].
BARE_PEN_PAGE = """<!doctype html><html><head><meta charset="utf-8"><title>bare pen echo</title>
<style>html, body { margin: 0; height: 100%; } #pad { position: fixed; inset: 0; touch-action: none; }</style></head>
<body><div id="pad"></div><script>
const bare = (window.__bare = { values: [], times: [], sent: 0, ready: false });
const ws = new WebSocket(`ws://${location.host}/ws`);
ws.onopen = () => { bare.ready = true; };
ws.onmessage = (ev) => { const now = performance.now(), t = JSON.parse(ev.data).t; bare.values.push(now - t); bare.times.push(t); };
const pad = document.getElementById("pad");
const kind = "onpointerrawupdate" in window ? "pointerrawupdate" : "pointermove";
bare.input = kind;
pad.addEventListener(kind, (ev) => {
  if (ev.buttons && ws.readyState === 1) { ws.send(JSON.stringify({ seq: bare.sent++, t: ev.timeStamp })); }
});
pad.addEventListener("pointerdown", (ev) => pad.setPointerCapture(ev.pointerId));
</script></body></html>"""


def serve_echo() -> None:
    """A bare WebSocket echo on the same stack (Starlette + uvicorn), for the reference.

    ``/ws`` echoes every text message; ``/pen`` is :data:`BARE_PEN_PAGE`.
    """
    import gc
    import socket

    import uvicorn
    from starlette.applications import Starlette
    from starlette.responses import HTMLResponse
    from starlette.routing import Route, WebSocketRoute

    async def echo(ws):
        await ws.accept()
        try:
            while True:
                await ws.send_text(await ws.receive_text())
        except Exception:
            pass

    async def pen(request):
        return HTMLResponse(BARE_PEN_PAGE)

    app = Starlette(routes=[WebSocketRoute("/ws", echo), Route("/pen", pen)])
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(128)
    print(f"echo at http://127.0.0.1:{sock.getsockname()[1]}/", flush=True)
    # Same WebSocket, thread-switch and collector settings as tactilize serve, so
    # the ratio isolates tactilize's own work (a full collection of the libraries'
    # objects once stopped this echo for 42 ms mid-stroke).
    sys.setswitchinterval(0.0005)
    gc.collect()
    gc.freeze()
    uvicorn.Server(uvicorn.Config(app, log_level="warning", ws_per_message_deflate=False)).run(sockets=[sock])


# ----------------------------------------------------------------- phases


def circle_sample(t_s, cx=33.9, cy=25.4, r=15.9, period_s=2.0, pressure=0.5):
    """A pen sample on a circle: time [ms], position [mm on the picture] (radius
    15.9 mm in 2 s: 50 mm/s), pressure, tilt."""
    a = 2 * math.pi * t_s / period_s
    return [t_s * 1e3, cx + r * math.cos(a), cy + r * math.sin(a), pressure, 0.0, 0.0]


def round_trips(ws, n, batch=4, interval_s=0.004, is_reply=lambda m: m.get("type") == "drive"):
    """Send n batches of pen samples, each waiting for its drive; returns RTTs [s]."""
    rtts = []
    t0 = time.perf_counter()
    for k in range(n):
        t = time.perf_counter() - t0
        rows = [circle_sample(t - (batch - 1 - i) * 0.001) for i in range(batch)]
        msg = json.dumps({"type": "samples", "batch": str(k), "samples": rows})
        s = time.perf_counter()
        ws.send(msg)
        while True:
            reply = json.loads(ws.recv(timeout=5))
            if is_reply(reply) and reply.get("batch") == str(k):
                break
        rtts.append(time.perf_counter() - s)
        # Pace like a pen (and leave the server idle between batches, as a page does).
        time.sleep(max(0.0, interval_s - (time.perf_counter() - s)))
    return rtts


def echo_round_trips(url, n, batch=4, interval_s=0.004):
    with connect(url, max_size=2**20) as ws:
        for _ in range(50):  # warm-up
            ws.send("{}")
            ws.recv(timeout=5)
        rtts = []
        t0 = time.perf_counter()
        for k in range(n):
            t = time.perf_counter() - t0
            rows = [circle_sample(t - (batch - 1 - i) * 0.001) for i in range(batch)]
            msg = json.dumps({"type": "samples", "batch": str(k), "samples": rows})
            s = time.perf_counter()
            ws.send(msg)
            ws.recv(timeout=5)
            rtts.append(time.perf_counter() - s)
            time.sleep(max(0.0, interval_s - (time.perf_counter() - s)))
    return rtts


def sustained(url, pid, seconds, rate_hz=1000):
    """One sample per message at rate_hz for `seconds`; memory sampled every second."""
    proc = psutil.Process(pid)
    received = {"drives": 0, "other": 0}
    stop_flag = threading.Event()
    rss = []
    with connect(url, max_size=2**20) as ws:
        ws.send(json.dumps({"type": "hello", "texture": "corduroy"}))
        while json.loads(ws.recv(timeout=10))["type"] != "ready":
            pass

        def reader():
            while not stop_flag.is_set():
                try:
                    m = json.loads(ws.recv(timeout=0.5))
                except TimeoutError:
                    continue
                except Exception:
                    return
                received["drives" if m.get("type") == "drive" else "other"] += 1

        th = threading.Thread(target=reader, daemon=True)
        th.start()
        t0 = time.perf_counter()
        next_rss = t0
        sent = 0
        late_max = 0.0
        while True:
            now = time.perf_counter()
            if now - t0 >= seconds:
                break
            if now >= next_rss:
                rss.append((now - t0, proc.memory_info().rss))
                next_rss += 1.0
            due = t0 + sent / rate_hz
            if now < due:
                time.sleep(min(due - now, 0.001))
                continue
            late_max = max(late_max, now - due)
            ws.send(json.dumps({"type": "samples", "batch": str(sent), "samples": [circle_sample(now - t0)]}))
            sent += 1
        elapsed = time.perf_counter() - t0
        time.sleep(0.2)
        stop_flag.set()
        th.join(timeout=2)
        rss.append((time.perf_counter() - t0, proc.memory_info().rss))
    return {"sent": sent, "elapsed_s": elapsed, "rate_hz": sent / elapsed, "received": received, "rss": rss, "late_max_s": late_max}


def pipeline_only(n, batch=4, interval_s=0.004):
    """The server's per-batch work without the network, in this process: parse
    the message, validate it, track, look up, apply the laws, drive the
    (simulated) output, serialise the reply.  Paced like a pen, so caches are
    as cold as in the server."""
    from tactilize.actuators.factory import open_output
    from tactilize.web.state import ServerState
    from tactilize.encode import dumps
    from tactilize.web.session import PenSession
    from tactilize.mapping import Profile

    out = open_output("simulated")
    try:
        state = ServerState(out, Profile.preset("paper"))
        sess = PenSession(state)
        sess.handle(json.dumps({"type": "texture", "id": "corduroy"}))
        times = []
        t0 = time.perf_counter()
        for k in range(n):
            t = time.perf_counter() - t0
            rows = [circle_sample(t - (batch - 1 - i) * 0.001) for i in range(batch)]
            text = json.dumps({"type": "samples", "batch": str(k), "samples": rows})
            s = time.perf_counter_ns()
            sess.handle(text)
            dumps(sess.render_pending(), compact=True)
            times.append(time.perf_counter_ns() - s)
            if interval_s:
                time.sleep(interval_s)
        sess.close()
    finally:
        out.close()
    return times


def flood(url, pid, seconds):
    """A client that sends 200-sample messages as fast as it can and never reads:
    the server must drop old samples (latest wins) and keep its memory flat."""
    proc = psutil.Process(pid)
    rss0 = proc.memory_info().rss
    t0 = time.perf_counter()
    n = 0
    try:
        with connect(url, max_size=2**20, close_timeout=1) as ws:
            ws.send(json.dumps({"type": "hello", "texture": "corduroy"}))
            t0 = time.perf_counter()
            while time.perf_counter() - t0 < seconds:
                rows = [[(n * 200 + i) * 0.05, 10 + (n * 200 + i) * 1e-4, 10.0, 0.5] for i in range(200)]
                ws.send(json.dumps({"type": "samples", "batch": str(n), "samples": rows}))
                n += 1
            rss1 = proc.memory_info().rss
    except Exception:  # the server may give up on a client that never reads: that is allowed
        rss1 = proc.memory_info().rss
    return {"messages": n, "samples": 200 * n, "seconds": time.perf_counter() - t0, "rss_start_mb": rss0 / 2**20, "rss_end_mb": rss1 / 2**20}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="length of the sustained 1 kHz phase [s]")
    ap.add_argument("--round-trips", type=int, default=3000, help="batches for the latency phases")
    ap.add_argument("--flood-seconds", type=float, default=10.0, help="length of the flood phase [s]")
    ap.add_argument("--output", default="simulated", help="server output spec")
    ap.add_argument("--json", action="store_true", help="print one JSON document")
    ap.add_argument("--serve-echo", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.serve_echo:
        serve_echo()
        return

    server, port = start([sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--port", "0", "--output", args.output])
    echo, echo_port = start([sys.executable, os.path.abspath(__file__), "--serve-echo"])
    base = f"http://127.0.0.1:{port}"
    url = f"ws://127.0.0.1:{port}/ws"
    try:
        httpx.get(base + "/api/textures", timeout=60)  # built-ins generated before timing
        with connect(url, max_size=2**20) as ws:
            ws.send(json.dumps({"type": "hello", "texture": "corduroy"}))
            while json.loads(ws.recv(timeout=10))["type"] != "ready":
                pass
            round_trips(ws, 200)  # warm-up
            rtt = round_trips(ws, args.round_trips)
        stats = httpx.get(base + "/api/stats", params={"last": args.round_trips}).json()
        ref = echo_round_trips(f"ws://127.0.0.1:{echo_port}/ws", args.round_trips)
        pipe = pipeline_only(min(args.round_trips, 2000))
        # Back to back: what the work costs when the CPU stays busy with it.
        pipe_hot = pipeline_only(min(args.round_trips, 2000), interval_s=0.0)
        sus = sustained(url, server.pid, args.seconds)
        stats_after = httpx.get(base + "/api/stats").json()
        c0 = stats_after["counters"]
        fl = flood(url, server.pid, args.flood_seconds)
        c1 = httpx.get(base + "/api/stats").json()["counters"]
        fl["counters"] = {k: c1.get(k, 0) - c0.get(k, 0) for k in c1}
    finally:
        stop(server)
        stop(echo)

    rss = sus["rss"]
    # Memory after the first 10 % of the run (allocator and caches warmed) vs the end.
    warm = rss[max(1, len(rss) // 10)][1] if len(rss) > 2 else rss[0][1]
    doc = {
        # 1-minute load average over the cores: the figures depend on it (shared machines)
        "load_average_1min": os.getloadavg()[0],
        "cpu_count": os.cpu_count(),
        "server_latency_us": {k: stats["server_latency_us"][k] for k in ("p50", "p90", "p99", "max")},
        "server_latency_batches": stats["batches"],
        "pipeline_only_us": {"p50": pct(pipe, 50) / 1e3, "p99": pct(pipe, 99) / 1e3},
        "pipeline_back_to_back_us": {"p50": pct(pipe_hot, 50) / 1e3, "p99": pct(pipe_hot, 99) / 1e3},
        "round_trip_ms": {"p50": pct(rtt, 50) * 1e3, "p99": pct(rtt, 99) * 1e3, "mean": statistics.fmean(rtt) * 1e3},
        "echo_round_trip_ms": {"p50": pct(ref, 50) * 1e3, "p99": pct(ref, 99) * 1e3},
        "round_trip_ratio_to_echo": {"p50": pct(rtt, 50) / pct(ref, 50), "p99": pct(rtt, 99) / pct(ref, 99)},
        "sustained": {
            "seconds": sus["elapsed_s"],
            "samples_sent": sus["sent"],
            "samples_per_s": sus["rate_hz"],
            "drives_received": sus["received"]["drives"],
            "other_messages": sus["received"]["other"],
            "client_late_max_ms": sus["late_max_s"] * 1e3,
            "rss_start_mb": rss[0][1] / 2**20,
            "rss_after_warmup_mb": warm / 2**20,
            "rss_end_mb": rss[-1][1] / 2**20,
            "rss_growth_after_warmup_mb": (rss[-1][1] - warm) / 2**20,
            # the server keeps the last 20,000 batches: the end of the sustained phase
            "server_latency_us_under_load": stats_after["server_latency_us"],
            "server_latency_batches_under_load": stats_after["batches"],
            "samples_dropped": stats_after["counters"].get("samples_dropped", 0),
        },
    }
    doc["flood"] = {
        **{k: v for k, v in fl.items() if k != "counters"},
        "samples_dropped": fl["counters"].get("samples_dropped", 0),
        "samples_received": fl["counters"].get("samples_received", 0),
        "drives_sent": fl["counters"].get("drives_sent", 0),
    }
    if args.json:
        print(json.dumps(doc, indent=2))
        return
    s = doc["sustained"]
    lat = doc["server_latency_us"]
    print(f"machine: {doc['cpu_count']} CPUs, load average {doc['load_average_1min']:.2f} at the end of the run")
    print(f"server-side latency (arrival -> drive sent), {args.round_trips} batches of 4 samples:")
    print(f"  p50 {lat['p50']:.0f} us   p99 {lat['p99']:.0f} us   max {lat['max']:.0f} us   (goal p99 < 1000 us)")
    pl = doc["pipeline_only_us"]
    ph = doc["pipeline_back_to_back_us"]
    print(f"  of which the pipeline itself (same work in-process, no network, paced): p50 {pl['p50']:.0f} us   p99 {pl['p99']:.0f} us")
    print(f"  the same pipeline back to back (CPU kept busy):                      p50 {ph['p50']:.0f} us   p99 {ph['p99']:.0f} us")
    r, e, q = doc["round_trip_ms"], doc["echo_round_trip_ms"], doc["round_trip_ratio_to_echo"]
    print("WebSocket round trip on loopback (batch -> its drive):")
    print(f"  tactilize p50 {r['p50']:.3f} ms   p99 {r['p99']:.3f} ms   (goal p99 < 5 ms)")
    print(f"  bare echo p50 {e['p50']:.3f} ms   p99 {e['p99']:.3f} ms   (same stack, reference)")
    print(f"  ratio     p50 {q['p50']:.2f}x     p99 {q['p99']:.2f}x")
    print(f"sustained: {s['samples_sent']} samples in {s['seconds']:.1f} s ({s['samples_per_s']:.0f}/s, one per message), "
          f"{s['drives_received']} drives back, {s['samples_dropped']} samples dropped by the server")
    print(f"  server RSS start {s['rss_start_mb']:.1f} MB, after warm-up {s['rss_after_warmup_mb']:.1f} MB, "
          f"end {s['rss_end_mb']:.1f} MB (growth after warm-up {s['rss_growth_after_warmup_mb']:+.2f} MB)")
    ul = s["server_latency_us_under_load"]
    print(f"  server-side latency under load: p50 {ul['p50']:.0f} us   p99 {ul['p99']:.0f} us")
    f = doc["flood"]
    print(f"flood (never reading): {f['samples']} samples in {f['seconds']:.1f} s; server dropped "
          f"{f['samples_dropped']} of {f['samples_received']} received (latest wins), rendered {f['drives_sent']} drives; "
          f"RSS {f['rss_start_mb']:.1f} -> {f['rss_end_mb']:.1f} MB")


if __name__ == "__main__":
    main()
