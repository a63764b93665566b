"""Bounded work for strangers: the server's memory under concurrent 16 Mpx uploads.

Starts ``tactilize serve`` (simulated output, a free port), lets it warm up (the
built-in maps), and measures in the same run:

* the *reference*: the server's resident memory at rest, warmed up;
* the peak resident memory while ``--uploads`` clients post a 16 Mpx picture each,
  all at once (a textured 4096 x 4096 JPEG, about 8 MB), and how each was answered
  (201 analysed, 503 refused beyond the upload limit);
* the same with one stroke export per client of a minute's stroke.

Prints the peak, the peak over the reference, and the answers.  The goal
(docs/serve.md "Bounds"): six concurrent 16 Mpx uploads peak within 600 MB.

Usage: python bench/bench_bounds.py [--uploads 6]
"""

from __future__ import annotations

import argparse
import io
import re
import subprocess
import sys
import threading
import time
from collections import Counter

import httpx
import numpy as np
import psutil
from PIL import Image


def picture() -> bytes:
    rng = np.random.default_rng(0)
    x = np.arange(4096)[None, :]
    a = (127 + 60 * np.sin(x / 7.0) + 30 * rng.standard_normal((4096, 4096))).clip(0, 255).astype("uint8")
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, "JPEG", quality=85)
    return buf.getvalue()


def stroke_body(texture: str, seconds: float = 60.0) -> dict:
    t = np.arange(0.0, seconds, 0.001)
    x = 5.0 + 20.0 * (1 + np.sin(t))
    return {"texture": texture, "format": "csv", "drive": "profile",
            "samples": [[float(a), float(b), 10.0, 0.5] for a, b in zip(t, x)]}


def watch(proc: psutil.Process, stop: threading.Event, peak: list[float]) -> None:
    while not stop.is_set():
        try:
            peak[0] = max(peak[0], proc.memory_info().rss / 2**20)
        except psutil.NoSuchProcess:
            return
        time.sleep(0.005)


def burst(n: int, post) -> Counter:
    answers: Counter = Counter()
    lock = threading.Lock()

    def one(i: int) -> None:
        try:
            got = post(i).status_code
        except httpx.HTTPError as exc:
            got = type(exc).__name__
        with lock:
            answers[got] += 1

    threads = [threading.Thread(target=one, args=(i,)) for i in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return answers


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uploads", type=int, default=6)
    args = ap.parse_args()
    data = picture()
    srv = subprocess.Popen([sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--port", "0"],
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        base = re.search(r"http://127\.0\.0\.1:\d+", srv.stdout.readline()).group(0)
        client = httpx.Client(base_url=base, timeout=300)
        client.get("/api/textures")  # waits for the built-in maps
        time.sleep(1.0)
        proc = psutil.Process(srv.pid)
        ref = proc.memory_info().rss / 2**20
        for label, post in (
            ("16 Mpx uploads", lambda i: client.post("/api/textures", files={"file": (f"p{i}.jpg", data + bytes([i]))},
                                                     data={"width_mm": str(100 + i)})),
            ("60 s stroke exports", lambda i: client.post("/api/export/stroke", json=stroke_body("corduroy"))),
        ):
            peak, stop = [ref], threading.Event()
            w = threading.Thread(target=watch, args=(proc, stop, peak))
            w.start()
            answers = burst(args.uploads, post)
            stop.set()
            w.join()
            print(f"{args.uploads} concurrent {label}: answers {dict(answers)}; reference (at rest) {ref:.0f} MB, "
                  f"peak {peak[0]:.0f} MB, peak / reference {peak[0] / ref:.2f}")
    finally:
        srv.terminate()
        srv.wait(timeout=30)


if __name__ == "__main__":
    main()
