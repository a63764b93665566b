"""Pulse events over the serial link: events per second, and the timing error at the board.

Runs the controller firmware in a process of its own behind a pseudo-terminal
(the emulator, reporting the instant of every pulse its channel-0 pin makes) and
drives it through :class:`~tactilize.actuators.serial.SerialOutput`:

- link: SerialOutput.play() with 9 pulses per channel (an EVENTS frame
  each) against the reference measured in the same run, SerialOutput.apply()
  with the windowed drive (a SET per channel): calls and pulses per second;
- board: minimum-jerk strokes over bump fields with known centres, rendered in
  real time by the surface's real-time path, played as scheduled pulses and, as
  the reference, as the windowed equivalent drive a version 3 board gets: p50 and
  p95 of |pulse on the pin - nearest true crossing|, and the share of pulses
  within 5 ms of one;
- the clock sync: residual [us], least round trip [us], drift [ppm].

Usage::

    python bench/bench_serial_events.py [--quick] [--json]

(``python bench/bench_surfaces.py --only serial`` runs the same.)
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import threading
import time

import numpy as np

from tactilize.actuators.serial import SerialOutput
from tactilize.drive import Drive
from tactilize.pen.samples import PenSample
from tactilize.pen.tracker import StrokeTracker
from tactilize.surface import surface_model
from tactilize.surface.equivalent import equivalent_drive
from tactilize.surface.events import PulseEvent
from tactilize.surface.rendering import Frame
from tactilize.surface.fields import bump_line_field, min_jerk_path
from tactilize.surface.stroke import SurfaceStroke

EMULATOR = r"""
import sys, time
from tactilize.boardhost import host_machine
from tactilize.boardhost.emulator import ControllerEmulator
emu = ControllerEmulator(assume_cold=True).start()
shift = time.monotonic() - time.perf_counter()
pin = emu.firmware.CHANNEL_PINS[0]
def edge(t, kind, p, detail):
    if kind == "gpio" and p == pin and detail.get("value") == 1:
        sys.stdout.write("%r\n" % (t + shift))
        sys.stdout.flush()
host_machine.add_listener(edge)
print(emu.device, flush=True)
sys.stdin.readline()
for start, _ in host_machine.pwm_pulses(pin):
    sys.stdout.write("%r\n" % (start + shift))
sys.stdout.write("end\n")
sys.stdout.flush()
sys.stdin.read()
emu.stop()
"""

OPERATING = Drive(40.0, 1e-3, strength=0.5)


class Emulator:
    """The firmware in its own process; ``pulses()`` the monotonic instants [s] of channel 0's pulses."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", EMULATOR], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True)
        self.device = self.proc.stdout.readline().strip()
        self._lines: list[str] = []
        self._done = threading.Event()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            if line.strip() == "end":
                self._done.set()
            else:
                self._lines.append(line)

    def pulses(self) -> np.ndarray:
        """Every pulse so far (soft-timer edges, then the PWM slice's pulses when closing)."""
        return np.sort(np.array([float(x) for x in list(self._lines)]))

    def close(self) -> np.ndarray:
        self.proc.stdin.write("\n")
        self.proc.stdin.flush()
        self._done.wait(10)
        out = self.pulses()
        self.proc.stdin.close()
        self.proc.wait(10)
        return out


def _crossings(t, x, y0, centres, radius):
    td = np.linspace(t[0], t[-1], int((t[-1] - t[0]) * 20_000) + 2)
    xd = np.interp(td, t, x)
    out = []
    for cx, cy in centres:
        d = np.hypot(xd - cx, y0 - cy)
        i = np.flatnonzero((d[1:-1] <= d[:-2]) & (d[1:-1] < d[2:]) & (d[1:-1] < radius)) + 1
        out.extend(td[i].tolist())
    return np.sort(np.array(out))


def _stroke(out: SerialOutput, seed: int, events: bool) -> tuple[float, np.ndarray]:
    """One stroke in real time; returns (host time of stroke time 0, true crossings [s])."""
    radius = 0.6e-3
    f, y0 = bump_line_field(seed, radius, beside=0)
    sm = surface_model(f.heights, pitch_m=f.pitch_m)
    t, x = min_jerk_path([3e-3, 41e-3, 24e-3, 62e-3], [0.7, 0.6, 0.9], [0.15, 0.2, 0.1])
    truth = _crossings(t, x, y0, f.centres_m, radius)
    tracker, stroke = StrokeTracker(), SurfaceStroke(sm)
    batches: list[list[PenSample]] = []
    for a, b in zip(t, x):
        smp = PenSample(float(a), float(b), y0)
        if batches and smp.t_s < batches[-1][0].t_s + 0.004:
            batches[-1].append(smp)
        else:
            batches.append([smp])
    origin = time.monotonic() + 0.1
    for batch in batches:
        delay = origin + batch[-1].t_s + 0.001 - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        state = tracker.extend(batch)
        if state is None:
            continue
        evs = stroke.update(batch, state.speed_m_s, state.direction_rad, state.pressure)
        if events:
            out.play(Frame(tuple(evs), OPERATING, False), batch[-1].t_s, [OPERATING])
        else:
            # The windowed drive, as a version 3 board gets it.
            d = equivalent_drive(stroke.recent(0.1), batch[-1].t_s)
            out.apply([d.replace(strength=min(1.0, d.strength or 0.5)) if not d.is_off else d])
    time.sleep(0.1)
    out.stop()
    return origin, truth


def _timing(pulses: np.ndarray, strokes: list[tuple[float, np.ndarray]]) -> dict[str, float]:
    errs = []
    for origin, truth in strokes:
        end = origin + 2.75
        for p in pulses[(pulses >= origin) & (pulses < end)]:
            errs.append(np.min(np.abs(origin + truth - p)))
    e = np.array(errs)
    crossings = sum(len(tr) for _, tr in strokes)
    return {"pulses": int(e.size), "crossings": crossings, "p50_ms": float(np.percentile(e, 50) * 1e3),
            "p95_ms": float(np.percentile(e, 95) * 1e3), "within_5ms": float(np.mean(e <= 0.005))}


def run(quick: bool = False) -> dict:
    n = 100 if quick else 400
    seeds = (101,) if quick else (101, 102, 108)
    emu = Emulator()
    res: dict = {}
    try:
        with SerialOutput(emu.device, closed_loop=False) as out:
            # link: the windowed SET drive (reference), then 9 scheduled pulses a channel
            t0 = time.perf_counter()
            for i in range(n):
                d = Drive(100.0 + i % 50, 300e-6)
                out.apply([d, d])
            set_s = (time.perf_counter() - t0) / n
            evs = [PulseEvent(0.5 + 0.0034 * k, 0.5) for k in range(9)]  # half a second ahead: replaced, never fired
            t0 = time.perf_counter()
            for i in range(n):
                out.play(Frame(tuple(evs), OPERATING, False), 0.001 * (i % 3), [OPERATING, OPERATING])
            ev_s = (time.perf_counter() - t0) / n
            out.stop()
            res["link"] = {"set_calls_per_s": 1 / set_s, "set_frames_per_s": 2 / set_s, "events_calls_per_s": 1 / ev_s,
                           "events_per_s": 18 / ev_s, "events_over_set_calls": set_s / ev_s}
            time.sleep(0.3)
            ev_strokes = [_stroke(out, s, True) for s in seeds]
            res["clock"] = {"residual_us": out.clock.residual_us, "rtt_us": out.clock.rtt_us,
                            "drift_ppm": out.clock.drift_ppm, "exchanges": out.clock.count}
            res["counts"] = out.event_counts[0]._asdict() if out.event_counts else None
            time.sleep(0.3)
            win_strokes = [_stroke(out, s, False) for s in seeds]
    finally:
        pulses = emu.close()
    res["board"] = {"events": _timing(pulses, ev_strokes), "windowed (reference)": _timing(pulses, win_strokes)}
    return res


def report(res: dict) -> None:
    link = res["link"]
    print("serial link to the emulator over a pty (both channels per call)")
    print(f"  reference: apply(), windowed SET drive   {link['set_calls_per_s']:8.0f} calls/s")
    print(f"  play(), 9 pulses a channel        {link['events_calls_per_s']:8.0f} calls/s"
          f" = {link['events_per_s']:.0f} events/s  ({link['events_over_set_calls']:.2f}x the SET calls)")
    c = res["clock"]
    print(f"clock sync: residual {c['residual_us']:.0f} us, least round trip {c['rtt_us']:.0f} us, "
          f"drift {c['drift_ppm']:+.1f} ppm over {c['exchanges']} exchanges")
    print("timing at the board: |pulse on the pin - nearest true crossing|")
    print(f"  {'drive':24s} {'pulses':>7s} {'crossings':>9s} {'p50 [ms]':>9s} {'p95 [ms]':>9s} {'<=5 ms':>7s}")
    ref = res["board"]["windowed (reference)"]
    for name, r in res["board"].items():
        print(f"  {name:24s} {r['pulses']:7d} {r['crossings']:9d} {r['p50_ms']:9.2f} {r['p95_ms']:9.2f} "
              f"{r['within_5ms']:7.2f}  p95/ref {r['p95_ms'] / ref['p95_ms']:.2f}")
    print(f"board counters (channel 0): {res['counts']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    res = run(a.quick)
    if a.json:
        print(json.dumps(res, indent=2))
    else:
        report(res)


if __name__ == "__main__":
    main()
