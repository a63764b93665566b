"""Benchmark: extract_features against a bare scipy.fft.rfft2 of the same array.

For square images of 256 to 4096 pixels, prints the median time of
``extract_features`` and of ``scipy.fft.rfft2(x, workers=1)`` on the same
float32 array, measured in the same run, their ratio, milliseconds per
megapixel, and time / (N^2 log2 N^2) normalised to the smallest size (flat
means N log N growth).  Goal (issue 2): ratio <= 1.5 at 1024.

Run: python bench/bench_features.py [--repeat R] [--sizes 256,512,...]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
import scipy.fft

import tactilize as tz


def median_time(fn, repeat: int) -> float:
    fn()  # warm caches (window, bases, FFT plans)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--sizes", default="256,512,1024,2048,4096")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    print(f"{'size':>6} {'features ms':>12} {'rfft2 ms':>10} {'ratio':>6} {'ms/MPx':>8} {'t/NlogN (rel)':>14}")
    base = None
    for n in (int(s) for s in args.sizes.split(",")):
        yy, xx = np.mgrid[0:n, 0:n]
        x = (0.5 + 0.3 * np.cos(2 * np.pi * (xx * 0.05 + yy * 0.02)) + 0.1 * rng.standard_normal((n, n)))
        x = np.clip(x, 0, 1).astype(np.float32)
        img = tz.load_image(x, dpi=300)
        repeat = max(3, args.repeat * 1024 * 1024 // (n * n)) if n < 1024 else max(3, args.repeat // (n // 1024))
        # interleave the two so that machine noise hits both alike
        t_feat, t_fft = [], []
        for _ in range(3):
            t_feat.append(median_time(lambda: tz.extract_features(img), repeat))
            t_fft.append(median_time(lambda: scipy.fft.rfft2(x, workers=1), repeat))
        tf, tr = min(t_feat), min(t_fft)
        nlogn = n * n * math.log2(n * n)
        base = base or tf / nlogn
        print(f"{n:>6} {tf * 1e3:>12.2f} {tr * 1e3:>10.2f} {tf / tr:>6.2f} {tf * 1e3 / (n * n / 1e6):>8.2f} {tf / nlogn / base:>14.2f}")


if __name__ == "__main__":
    main()
