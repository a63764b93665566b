"""The chip model's ticks against the real MicroPython's: the same inputs around
the wrap and at the overflow bound give the same results and the same
OverflowError in the WebAssembly MicroPython's ``time`` module and in
tactilize.boardhost.rp2040 (run on the host, and inside MicroPython too)."""

from __future__ import annotations

import json

from test_firmware_micropython import micropython

from tactilize.boardhost import rp2040 as R

HALF = 1 << 29
TICKS = [0, 1, HALF - 1, HALF, HALF + 1, (1 << 30) - 2, (1 << 30) - 1]
DELTAS = [0, 1, -1, 1000, -1000, HALF - 1, -(HALF - 1), HALF, -HALF, HALF + 5, -(HALF + 5), (1 << 30) - 1]

CODE = """
import sys, json, time
sys.path.insert(0, "/")
import rp2040
T = %s
D = %s
def run(add, diff):
    out = []
    for t in T:
        for d in D:
            try:
                out.append(add(t, d))
            except OverflowError as e:
                out.append("OverflowError: " + str(e))
    for a in T:
        for b in T:
            out.append(diff(a, b))
    return out
print("RESULT " + json.dumps({"mp": run(time.ticks_add, time.ticks_diff),
                              "model": run(rp2040.ticks_add, rp2040.ticks_diff),
                              "wrap": time.ticks_add((1 << 30) - 1, 1)}))
"""


def _host(add, diff):
    out: list = []
    for t in TICKS:
        for d in DELTAS:
            try:
                out.append(add(t, d))
            except OverflowError as e:
                out.append("OverflowError: " + str(e))
    for a in TICKS:
        for b in TICKS:
            out.append(diff(a, b))
    return out


def test_ticks_add_and_diff_agree_with_micropython():
    text = micropython(CODE % (TICKS, DELTAS))
    got = json.loads([line for line in text.splitlines() if line.startswith("RESULT ")][0][7:])
    assert got["wrap"] == 0  # this MicroPython's ticks period is 2**30 too
    assert got["model"] == got["mp"]
    assert _host(R.ticks_add, R.ticks_diff) == got["mp"]
    assert "OverflowError: ticks interval overflow" in got["mp"]
