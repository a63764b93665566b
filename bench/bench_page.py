"""Event-to-drive latency in the real page: headless Chromium, trusted pen events.

Starts ``tactilize serve`` and a bare WebSocket echo server (the reference of
``bench_web.py``) on free loopback ports, opens the page in headless Chromium,
and strokes the picture with trusted pen events (Chrome DevTools Protocol
``Input.dispatchMouseEvent`` with ``pointerType: "pen"``, sent at the pen's
own rate, 250 Hz by default, without waiting for each event's acknowledgement,
from a bare DevTools client with no automation driver: see :class:`DevTools`).
It prints, from one run:

1. event-to-drive latency in the page: for each pen batch the page sends, the
   time from its last sample's own ``timeStamp`` to the drive covering it
   arriving back in the page (p50, p99, max) [ms].  Measured by a script
   injected before the page's own (it wraps ``WebSocket``), so the same
   measurement works on any version of the page;
2. what the page's own live readout says (when the page has one);
3. the server-side latency of the same batches (arrival -> drive sent, from
   ``/api/stats``) [us];
4. the bare-echo reference: the page's round trip to an echo WebSocket on the
   same stack (Starlette on uvicorn), paced like a pen [ms];
5. the bare-pen-echo reference, the floor of this browser and machine: the same
   strokes on a page that does nothing but send each raw update's own
   ``timeStamp`` to that echo and note its return (``bench_web.BARE_PEN_PAGE``)
   [ms], half of them before the pen page and half after.  Whatever the pen
   page does, it cannot beat this; the ratio to it is what the page and the
   server add.  The CPU each process used during the floor's strokes is
   printed too: on a shared machine the same work can cost twice the CPU
   time at one hour as at another, so it tells which kind of run this was.

Goal (docs/references.md, section 9 (simultaneity)): p99 under 5 ms on loopback.

Usage::

    python bench/bench_page.py                 # a warm-up stroke, then 4 strokes of 1.5 s
    python bench/bench_page.py --strokes 8 --json

No assertion on wall-clock time: figures are printed.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time

import httpx

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_web import pct, start, stop  # noqa: E402

CHROMIUM = os.environ.get("TACTILIZE_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]

# Runs before the page's scripts: remembers the newest sample timestamp of each
# batch sent, and when a drive comes back, the delay of every batch it covers.
INSTRUMENT = r"""
(() => {
  const lat = (window.__benchLatency = { pending: [], values: [], times: [], batches: 0, rows: 0 });
  const Native = window.WebSocket;
  const send = Native.prototype.send;
  Native.prototype.send = function (data) {
    if (typeof data === "string" && data.includes('"samples"')) {
      try {
        const m = JSON.parse(data);
        if (m.type === "samples" && m.samples.length) {
          lat.pending.push([Number(m.batch), m.samples[m.samples.length - 1][0]]);
          lat.batches++; lat.rows += m.samples.length;
        }
      } catch (e) { /* not ours */ }
    }
    return send.call(this, data);
  };
  window.WebSocket = class extends Native {
    constructor(...args) {
      super(...args);
      this.addEventListener("message", (ev) => {
        const now = performance.now();
        let m; try { m = JSON.parse(ev.data); } catch (e) { return; }
        if (m.type !== "drive" || m.resting || m.batch == null) return;
        while (lat.pending.length && lat.pending[0][0] <= Number(m.batch)) {
          const t = lat.pending.shift()[1];
          lat.values.push(now - t); lat.times.push(t);
        }
      });
    }
  };
})();
"""

ECHO_IN_PAGE = """async ([url, n]) => {
  const ws = new WebSocket(url);
  await new Promise((ok, bad) => { ws.onopen = ok; ws.onerror = bad; });
  const rtt = [];
  const body = JSON.stringify({type: "samples", batch: "0", samples: [[0, 10, 10, 0.5, 0, 0]]});
  for (let i = 0; i < n; i++) {
    const t = performance.now();
    await new Promise((ok) => { ws.onmessage = ok; ws.send(body); });
    rtt.push(performance.now() - t);
    await new Promise((ok) => setTimeout(ok, 4));
  }
  ws.close();
  return rtt;
}"""


class DevTools:
    """A bare DevTools protocol client on one page target: no automation driver.

    The benchmark talks to Chromium itself, over one WebSocket: a driver such as
    Playwright's listens to every frame the page's socket sends and receives (on
    this page, 500 a second) in two more processes, load a user's browser never
    carries.  ``fire`` sends without waiting for the reply: the browser
    acknowledges a mouse move only after the page's next frame, so a client that
    waits sends pen events at the frame rate (60 Hz), not the pen's.
    """

    def __init__(self, ws_url: str) -> None:
        from websockets.sync.client import connect as ws_connect

        self.ws = ws_connect(ws_url, max_size=None, compression=None)
        self.id = 0
        self.replies: dict[int, dict] = {}
        self.arrived = threading.Condition()
        self.errors: list = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        try:
            for text in self.ws:
                m = json.loads(text)
                if "id" in m:
                    with self.arrived:
                        self.replies[m["id"]] = m
                        self.arrived.notify_all()
        except Exception:  # closed
            pass

    def fire(self, method: str, params: dict | None = None) -> int:
        self.id += 1
        self.ws.send(json.dumps({"id": self.id, "method": method, "params": params or {}}))
        return self.id

    def call(self, method: str, params: dict | None = None, timeout: float = 60.0) -> dict:
        i = self.fire(method, params)
        with self.arrived:
            if not self.arrived.wait_for(lambda: i in self.replies, timeout):
                raise SystemExit(f"DevTools: no reply to {method} in {timeout} s")
            m = self.replies.pop(i)
        if "error" in m:
            raise SystemExit(f"DevTools: {method}: {m['error']}")
        return m["result"]

    def evaluate(self, expression: str, timeout: float = 60.0):
        r = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True, "awaitPromise": True}, timeout)
        if "exceptionDetails" in r:
            raise SystemExit(f"in the page: {r['exceptionDetails'].get('exception', {}).get('description', r['exceptionDetails'])}")
        return r["result"].get("value")

    def wait_for(self, expression: str, timeout: float = 30.0) -> None:
        t0 = time.perf_counter()
        while not self.evaluate(expression):
            if time.perf_counter() - t0 > timeout:
                raise SystemExit(f"the page never satisfied: {expression}")
            time.sleep(0.05)

    def pen(self, kind: str, x: float, y: float, buttons: int) -> None:
        self.fire("Input.dispatchMouseEvent", {
            "type": kind, "x": x, "y": y, "button": "left", "buttons": buttons,
            "clickCount": 0 if kind == "mouseMoved" else 1, "pointerType": "pen",
            "force": 0.5 if buttons else 0.0, "tiltX": 10, "tiltY": -5})

    def stroke(self, x0: float, y0: float, v_px_s: float, seconds: float, interval_s: float) -> int:
        """One stroke to the right at v_px_s [CSS px/s], one move every interval_s [s]; returns the moves sent."""
        self.pen("mousePressed", x0, y0, 1)
        t0 = time.perf_counter()
        n = 0
        x = x0
        while (t := time.perf_counter() - t0) < seconds:
            n += 1
            x = x0 + v_px_s * t
            self.pen("mouseMoved", x, y0, 1)
            # Sleep to the next event's due time (not a fixed sleep): the rate stays the pen's.
            time.sleep(max(0.0, t0 + n * interval_s - time.perf_counter()))
        self.pen("mouseReleased", x, y0, 0)
        return n

    def close(self) -> None:
        self.ws.close()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def open_chromium(profile_dir: str):
    """Headless Chromium with a DevTools port; returns (process, client on its page)."""
    port = free_port()
    proc = subprocess.Popen([CHROMIUM, *CHROMIUM_ARGS, f"--remote-debugging-port={port}", f"--user-data-dir={profile_dir}",
                             "--window-size=1280,800", "about:blank"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0 = time.perf_counter()
    while True:
        try:
            pages = [t for t in httpx.get(f"http://127.0.0.1:{port}/json/list", timeout=2).json() if t["type"] == "page"]
            if pages:
                return proc, DevTools(pages[0]["webSocketDebuggerUrl"])
        except (httpx.HTTPError, ValueError):
            pass
        if proc.poll() is not None or time.perf_counter() - t0 > 30:
            proc.kill()
            raise SystemExit(f"Chromium did not start ({CHROMIUM})")
        time.sleep(0.1)


def cpu_times(browser_pid: int, server_pid: int) -> dict[str, float]:
    """CPU time used so far [s] by each part: Chromium's processes by type, the server, this benchmark."""
    import psutil

    out: dict[str, float] = {}

    def add(kind: str, proc) -> None:
        try:
            t = proc.cpu_times()
            out[kind] = out.get(kind, 0.0) + t.user + t.system
        except psutil.Error:
            pass

    root = psutil.Process(browser_pid)
    add("browser", root)
    for child in root.children(recursive=True):
        cmd = " ".join(child.cmdline()) if child.is_running() else ""
        kind = ("renderer" if "--type=renderer" in cmd else "gpu" if "--type=gpu" in cmd
                else "network" if "NetworkService" in cmd else "chromium (other)")
        add(kind, child)
    add("server", psutil.Process(server_pid))
    add("this benchmark", psutil.Process())
    return out


def floor_strokes(page: DevTools, echo_port: int, strokes: int, seconds: float, interval_s: float,
                  pids: tuple[int, int]) -> tuple[list[float], list[float], str, dict[str, float], float]:
    """The floor: ``strokes`` strokes on the bare pen page (``bench_web.BARE_PEN_PAGE``);
    returns each pen event's event -> echo time [ms] and timestamp [ms], the event it listened to,
    the CPU time [s] each part used during the strokes (``pids``: the browser and
    the echo server, counted as "server") and the strokes' wall time [s]."""
    page.call("Page.navigate", {"url": f"http://127.0.0.1:{echo_port}/pen"})
    page.wait_for("window.__bare && window.__bare.ready")
    page.stroke(100, 100, 20 / (25.4 / 96), 0.5, interval_s)  # not counted, like the pen page's first
    time.sleep(0.3)
    page.evaluate("window.__bare.values = []; window.__bare.times = []")
    cpu0, wall0 = cpu_times(*pids), time.perf_counter()
    for k in range(strokes):
        page.stroke(100, 130 + 12 * k, 20 / (25.4 / 96), seconds, interval_s)
        time.sleep(0.3)
    cpu1, wall1 = cpu_times(*pids), time.perf_counter()
    got = page.evaluate("({values: window.__bare.values, times: window.__bare.times, input: window.__bare.input})")
    return got["values"], got["times"], got["input"], {k: cpu1[k] - cpu0.get(k, 0.0) for k in cpu1}, wall1 - wall0


#: Batches counted as a stroke's start: the first ones after a pause are slower
#: at every hop (caches and processes gone cold), so they are shown apart.
START_BATCHES = 5


def by_stroke_position(times_ms: list[float], values_ms: list[float], gap_ms: float = 100.0) -> dict:
    """Event-to-drive [ms] of the first :data:`START_BATCHES` batches of each
    stroke and of the rest; strokes are told apart by a gap of ``gap_ms`` [ms]
    between consecutive batches' newest samples."""
    start, rest = [], []
    k, prev = 0, None
    for t, v in zip(times_ms, values_ms):
        # A new page load starts its clock again: a timestamp going back is a new stroke too.
        k = 0 if prev is None or not 0 <= t - prev <= gap_ms else k + 1
        prev = t
        (start if k < START_BATCHES else rest).append(v)
    return {
        "stroke_start": {"n": len(start), "p50": pct(start, 50), "max": max(start) if start else None},
        "rest": {"n": len(rest), "p50": pct(rest, 50), "p99": pct(rest, 99), "max": max(rest) if rest else None},
    }


def position_line(what: str, pos: dict) -> str:
    """One printed line of :func:`by_stroke_position`'s result."""
    a, z = pos["stroke_start"], pos["rest"]
    return (f"  first {START_BATCHES} {what} of each stroke ({a['n']}): p50 {a['p50']:.2f} ms   max {a['max']:.2f} ms;   "
            f"the rest ({z['n']}): p50 {z['p50']:.2f} ms   p99 {z['p99']:.2f} ms   max {z['max']:.2f} ms")


def run(strokes: int, seconds: float, echo_n: int, rate_hz: float) -> dict:
    server, port = start([sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--port", "0"])
    echo, echo_port = start([sys.executable, os.path.join(os.path.dirname(os.path.abspath(__file__)), "bench_web.py"), "--serve-echo"])
    base = f"http://127.0.0.1:{port}/"
    browser = None
    try:
        httpx.get(base + "api/textures", timeout=60)
        with tempfile.TemporaryDirectory(prefix="bench-page-", ignore_cleanup_errors=True) as profile_dir:
            browser, page = open_chromium(profile_dir)
            try:
                page.call("Page.enable")
                page.call("Page.addScriptToEvaluateOnNewDocument", {"source": INSTRUMENT})
                page.call("Emulation.setDeviceMetricsOverride", {"width": 1280, "height": 800, "deviceScaleFactor": 1, "mobile": False})
                # The floor before and after the pen page, half its strokes each, so a
                # machine that gets busier or quieter during the run weighs on both alike.
                interval = 1.0 / rate_hz
                bare, bare_times, bare_input, bare_cpu, bare_wall = floor_strokes(page, echo_port, max(1, strokes // 2), seconds, interval, (browser.pid, echo.pid))
                page.call("Page.navigate", {"url": base})
                page.wait_for("document.body && document.body.dataset.ready === 'true' && !!window.tactilize.settings && !!window.tactilize.settings.texture")
                page.evaluate("window.tactilize.texture !== 'corduroy' && document.querySelector('[data-testid=texture][data-id=corduroy]').click()")
                page.wait_for("window.tactilize.settings.texture === 'corduroy' && document.querySelector('#picture').complete")
                box = page.evaluate("(() => { const r = document.querySelector('#picture').getBoundingClientRect(); return {x: r.x, y: r.y}; })()")
                # One stroke not counted: the page's first drives pay for compiling and first paints.
                page.stroke(box["x"] + 10, box["y"] + 20, 20 / (25.4 / 96), 0.5, interval)
                time.sleep(0.3)
                page.evaluate("window.__benchLatency.values = []; window.__benchLatency.times = []; window.__benchLatency.batches = 0; window.__benchLatency.rows = 0")
                stats0 = httpx.get(base + "api/stats").json()
                moves = 0
                readouts = []
                cpu0, wall0 = cpu_times(browser.pid, server.pid), time.perf_counter()
                for k in range(strokes):
                    # 20 mm/s across the picture (at 1/96 inch per CSS px), then a pause.
                    moves += page.stroke(box["x"] + 10, box["y"] + 30 + 12 * k, 20 / (25.4 / 96), seconds, interval)
                    time.sleep(0.05)
                    readouts.append(page.evaluate("window.tactilize.latency ? window.tactilize.latency.last : null"))
                    time.sleep(0.25)
                cpu1, wall1 = cpu_times(browser.pid, server.pid), time.perf_counter()
                time.sleep(0.3)
                lat = page.evaluate("({values: window.__benchLatency.values, times: window.__benchLatency.times, batches: window.__benchLatency.batches, rows: window.__benchLatency.rows})")
                mode = page.evaluate("window.tactilize.inputMode || 'pointermove'")
                drawing = page.evaluate("window.tactilize.drawing || 'page'")
                stats = httpx.get(base + "api/stats", params={"last": lat["batches"]}).json()
                more, more_times, _, more_cpu, more_wall = floor_strokes(page, echo_port, max(1, strokes - strokes // 2), seconds, interval, (browser.pid, echo.pid))
                bare += more
                bare_times += more_times
                bare_wall += more_wall
                for k, t in more_cpu.items():
                    bare_cpu[k] = bare_cpu.get(k, 0.0) + t
                echo_rtt = page.evaluate(f"({ECHO_IN_PAGE})({json.dumps([f'ws://127.0.0.1:{echo_port}/ws', echo_n])})", timeout=120)
            finally:
                page.close()
                browser.terminate()
                browser.wait(10)
    finally:
        stop(server)
        stop(echo)
    v = lat["values"]
    b = bare
    c0, c1 = stats0["counters"], stats["counters"]
    return {
        "load_average_1min": os.getloadavg()[0],
        "cpu_count": os.cpu_count(),
        "input": mode,
        "drawing": drawing,
        "pen_events": moves,
        "pen_rate_hz": moves / (strokes * seconds),
        "batches_sent": lat["batches"],
        "samples_sent": lat["rows"],
        "samples_received_by_server": c1.get("samples_received", 0) - c0.get("samples_received", 0),
        "event_to_drive_ms": {"n": len(v), "p50": pct(v, 50), "p99": pct(v, 99), "max": max(v) if v else None},
        "event_to_drive_by_position_ms": by_stroke_position(lat["times"], v),
        "page_readout_ms": readouts,
        "server_latency_us": stats["server_latency_us"],
        "cpu_percent_during_strokes": {k: round(100 * (cpu1[k] - cpu0.get(k, 0.0)) / (wall1 - wall0), 1) for k in cpu1},
        "echo_in_page_ms": {"p50": pct(echo_rtt, 50), "p99": pct(echo_rtt, 99), "max": max(echo_rtt)},
        "ratio_to_echo": {"p50": pct(v, 50) / pct(echo_rtt, 50), "p99": pct(v, 99) / pct(echo_rtt, 99)},
        "bare_pen_echo_ms": {"input": bare_input, "n": len(b), "p50": pct(b, 50), "p99": pct(b, 99), "max": max(b) if b else None},
        "bare_pen_echo_by_position_ms": by_stroke_position(bare_times, b),
        "cpu_percent_during_bare_pen_strokes": {k: round(100 * t / bare_wall, 1) for k, t in bare_cpu.items()},
        "ratio_to_bare_pen_echo": {"p50": pct(v, 50) / pct(b, 50), "p99": pct(v, 99) / pct(b, 99)},
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--strokes", type=int, default=4, help="pen strokes")
    ap.add_argument("--seconds", type=float, default=1.5, help="length of each stroke [s]")
    ap.add_argument("--rate", type=float, default=250.0, help="pen report rate [Hz]")
    ap.add_argument("--echo", type=int, default=500, help="round trips to the bare echo from the page")
    ap.add_argument("--json", action="store_true", help="print one JSON document")
    args = ap.parse_args(argv)
    doc = run(args.strokes, args.seconds, args.echo, args.rate)
    if args.json:
        print(json.dumps(doc, indent=2))
        return
    e, s, r = doc["event_to_drive_ms"], doc["server_latency_us"], doc["echo_in_page_ms"]
    print(f"machine: {doc['cpu_count']} CPUs, load average {doc['load_average_1min']:.2f}")
    print(f"page input: {doc['input']}, drawing in the {doc['drawing']}; {doc['pen_events']} pen events ({doc['pen_rate_hz']:.0f} Hz) -> {doc['samples_sent']} samples in "
          f"{doc['batches_sent']} batches; the server received {doc['samples_received_by_server']} samples")
    print(f"event -> drive in the page ({e['n']} batches): p50 {e['p50']:.2f} ms   p99 {e['p99']:.2f} ms   "
          f"max {e['max']:.2f} ms   (goal p99 < 5 ms)")
    print(position_line("batches", doc["event_to_drive_by_position_ms"]))
    shown = [x for x in doc["page_readout_ms"] if x]
    if shown:
        print("  the page's own readout after each stroke (last second): "
              + ", ".join(f"p50 {x['p50']:.1f} / p99 {x['p99']:.1f} ms" for x in shown))
    print(f"server side, same batches (arrival -> drive sent): p50 {s['p50']:.0f} us   p99 {s['p99']:.0f} us   max {s['max']:.0f} us")
    cpu = doc["cpu_percent_during_strokes"]
    print("CPU during the strokes [% of one core]: " + ", ".join(f"{k} {v:.0f}" for k, v in sorted(cpu.items(), key=lambda kv: -kv[1]))
          + f"; {sum(cpu.values()):.0f} of {100 * doc['cpu_count']}")
    print(f"bare echo from the page (reference, same stack): p50 {r['p50']:.2f} ms   p99 {r['p99']:.2f} ms   max {r['max']:.2f} ms")
    print(f"ratio event -> drive / bare echo: p50 {e['p50'] / r['p50']:.2f}   p99 {e['p99'] / r['p99']:.2f}")
    b = doc["bare_pen_echo_ms"]
    print(f"bare pen echo (reference, floor: the same strokes on a page that only echoes each {b['input']}'s timestamp, "
          f"{b['n']} events): p50 {b['p50']:.2f} ms   p99 {b['p99']:.2f} ms   max {b['max']:.2f} ms")
    print(position_line("events", doc["bare_pen_echo_by_position_ms"]))
    cpu = doc["cpu_percent_during_bare_pen_strokes"]
    print("  CPU during its strokes [% of one core]: " + ", ".join(f"{k} {v:.0f}" for k, v in sorted(cpu.items(), key=lambda kv: -kv[1]))
          + f"; {sum(cpu.values()):.0f} of {100 * doc['cpu_count']} (\"server\": the bare echo)")
    q = doc["ratio_to_bare_pen_echo"]
    print(f"ratio event -> drive / bare pen echo: p50 {q['p50']:.2f}   p99 {q['p99']:.2f}")


if __name__ == "__main__":
    main()
