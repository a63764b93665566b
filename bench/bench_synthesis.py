"""Benchmark: pulse-train synthesis, x real time, two channels at 48 kHz.

Renders 20 s of the pen's two channels (phantom mode, 300 Hz, 150 us pulses, the
densest drive the paper's actuator takes) with :class:`tactilize.PenStream`
block by block, for several block sizes, with the drive unchanged and with a new
drive every block (a stroke changing speed).  References measured in the same
run: the one-shot :func:`tactilize.pulse_train` of both channels, and the floor
cost of producing the frames at all (``np.zeros((n, 2), float32)`` plus a copy).
Goal: >= 2000 x real time for two channels at 48 kHz.

Run: python bench/bench_synthesis.py [--seconds S] [--repeat R]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import tactilize as tz

FS = 48_000


def median_time(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    seconds = args.seconds
    n_total = int(seconds * FS)
    drive = tz.Drive(300.0, 150e-6, 1.0)

    def floor_cost():
        out = np.zeros((n_total, 2), dtype=np.float32)
        out.copy()

    def one_shot():
        np.stack([tz.pulse_train(drive, seconds, FS), tz.pulse_train(drive, seconds, FS)], axis=1)

    t_floor = median_time(floor_cost, args.repeat)
    t_oneshot = median_time(one_shot, args.repeat)
    print(f"two channels at {FS} Hz, {seconds:g} s of signal, drive 300 Hz / 150 us")
    print(f"  reference: zeros + copy        {seconds / t_floor:10.0f} x real time")
    print(f"  reference: one-shot pulse_train{seconds / t_oneshot:10.0f} x real time")
    print(f"  {'block':>7} {'steady x RT':>12} {'changing x RT':>14} {'vs one-shot':>12}")
    for block in (128, 512, 1024, 4800, 48_000):
        nb = n_total // block

        def steady(block=block, nb=nb):
            s = tz.PenStream(FS)
            s.set_drive(drive, 0.7)
            for _ in range(nb):
                s.render(block)

        rng = np.random.default_rng(0)
        drives = [tz.Drive(float(f), 150e-6 * 300 / float(f)) for f in rng.uniform(100, 300, size=64)]

        def changing(block=block, nb=nb):
            s = tz.PenStream(FS)
            for i in range(nb):
                s.set_drive(drives[i % 64], 0.1 * (i % 31))
                s.render(block)

        t_s = median_time(steady, args.repeat)
        t_c = median_time(changing, args.repeat)
        print(f"  {block:>7} {seconds / t_s:12.0f} {seconds / t_c:14.0f} {t_oneshot / t_s:12.2f}")


if __name__ == "__main__":
    main()
