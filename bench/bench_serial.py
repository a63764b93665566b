"""Host-to-controller command round trip over a pseudo-terminal.

Runs ``tactilize controller-emulator`` in a subprocess and measures, over N
requests each:

- reference: a bare pty echo in a subprocess (select + read + write, no
  protocol), the floor any command round trip through a pty pays;
- raw frame: one HEARTBEAT frame written with pyserial, its ACK decoded with
  the host FrameDecoder (protocol plus firmware, no library threads);
- the same HEARTBEAT through SerialOutput's request path (sequence matching,
  reader thread wake-up, with its own heartbeat thread running);
- SerialOutput.status(): the library's request path (sequence matching, reader
  thread wake-up) for a STATUS request and its 64-byte reply;
- SerialOutput.apply(): two SET frames, each acknowledged, plus the envelope.

Prints p50 and p99 for each and the ratio to the echo reference measured in the
same run.  Usage::

    python bench/bench_serial.py [--n 2000]
"""

from __future__ import annotations

import argparse
import select
import subprocess
import sys
import threading
import time

import numpy as np
import serial

from tactilize.actuators import frames as P
from tactilize.actuators.serial import SerialOutput
from tactilize.mapping import Drive

ECHO_SERVER = r"""
import os, select, sys, tty
master, slave = os.openpty()
tty.setraw(slave)
print(os.ttyname(slave), flush=True)
while True:
    select.select([master], [], [])
    os.write(master, os.read(master, 4096))
"""


def start(cmd: list[str]) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    ready, _, _ = select.select([proc.stdout], [], [], 30.0)
    if not ready:
        proc.kill()
        raise SystemExit(f"{cmd[:3]} printed no device path")
    device = proc.stdout.readline().strip()
    # Keep reading the emulator's JSON lines: a full pipe would block it.
    threading.Thread(target=proc.stdout.read, daemon=True).start()
    return proc, device


def read_exactly(ser: serial.Serial, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = ser.read(n - len(data))
        if not chunk:
            raise SystemExit("timed out waiting for a reply")
        data += chunk
    return data


def echo_round_trips(device: str, n: int) -> np.ndarray:
    frame = P.encode_frame(1, P.Command.HEARTBEAT)
    out = np.empty(n)
    with serial.Serial(device, timeout=1.0) as ser:
        for i in range(n):
            t0 = time.perf_counter()
            ser.write(frame)
            read_exactly(ser, len(frame))
            out[i] = time.perf_counter() - t0
    return out


def raw_frame_round_trips(device: str, n: int) -> np.ndarray:
    out = np.empty(n)
    dec = P.FrameDecoder()
    with serial.Serial(device, timeout=1.0) as ser:
        for i in range(n):
            frame = P.encode_frame(i, P.Command.HEARTBEAT)
            t0 = time.perf_counter()
            ser.write(frame)
            got: list[P.Frame] = []
            while not got:
                chunk = ser.read(max(1, ser.in_waiting))
                if not chunk:
                    raise SystemExit("no ACK from the emulator")
                got = dec.feed(chunk)
            out[i] = time.perf_counter() - t0
            assert got[0].command == P.Command.ACK and got[0].seq == i & 0xFF
    return out


def library_round_trips(device: str, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    beat = np.empty(n)
    status = np.empty(n)
    apply = np.empty(n)
    with SerialOutput(device) as out:
        for i in range(n):
            # the library's request path for the same frame as the raw row
            t0 = time.perf_counter()
            out._request(P.Command.HEARTBEAT)
            beat[i] = time.perf_counter() - t0
        for i in range(n):
            t0 = time.perf_counter()
            out.status()
            status[i] = time.perf_counter() - t0
        for i in range(n):
            d = Drive(100.0 + i % 100, 300e-6)
            t0 = time.perf_counter()
            out.apply([d, d])
            apply[i] = time.perf_counter() - t0
    return beat, status, apply


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2000, help="round trips per measurement")
    args = ap.parse_args()

    echo_proc, echo_dev = start([sys.executable, "-c", ECHO_SERVER])
    emu_proc, emu_dev = start([sys.executable, "-m", "tactilize.cli", "controller-emulator"])
    try:
        # warm up both paths (imports, page faults) before measuring
        echo_round_trips(echo_dev, 50)
        raw_frame_round_trips(emu_dev, 50)
        ref = echo_round_trips(echo_dev, args.n)
        raw = raw_frame_round_trips(emu_dev, args.n)
        beat, status, apply = library_round_trips(emu_dev, args.n)
    finally:
        for p in (echo_proc, emu_proc):
            p.terminate()
            p.wait(5)

    ref50, ref99 = np.percentile(ref, [50, 99])
    print(f"host-to-emulator round trip over a pty, n = {args.n} each")
    print(f"{'path':44s} {'p50 [us]':>9s} {'p99 [us]':>9s} {'p50/ref':>8s} {'p99/ref':>8s}")
    rows = [
        ("reference: bare pty echo (6 bytes)", ref),
        ("raw HEARTBEAT frame -> ACK (firmware)", raw),
        ("SerialOutput HEARTBEAT -> ACK (library)", beat),
        ("SerialOutput.status() (STATUS -> 64 B)", status),
        ("SerialOutput.apply() (2 x SET -> ACK)", apply),
    ]
    for name, x in rows:
        p50, p99 = np.percentile(x, [50, 99])
        print(f"{name:44s} {p50 * 1e6:9.0f} {p99 * 1e6:9.0f} {p50 / ref50:8.1f} {p99 / ref99:8.1f}")


if __name__ == "__main__":
    main()
