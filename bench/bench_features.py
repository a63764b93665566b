"""Benchmark: extract_features against a bare scipy.fft.rfft2 of the same array.

For square images of 256 to 4096 pixels, prints the time of ``extract_features``
and of ``scipy.fft.rfft2(x, workers=1)`` on the same float32 array, measured in
the same run, their ratio, milliseconds per megapixel, and time / (N^2 log2 N^2)
normalised to the smallest size (flat means N log N growth), for both: beyond
the caches the bare FFT itself grows faster than N log N, and a flat ratio says
the analysis grows as the FFT does.  Goal: ratio <= 1.5 at 1024.

The two calls alternate, one of each per pair, and the ratio printed is the
median of the pairs' ratios (with its quartiles): on a shared machine a
neighbour's burst, or the clock changing speed, hits both members of a pair
alike, where separate medians of the two drift apart (the same code measured
1.4 and 1.8 that way within a minute).  The times are the medians of each.

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


def paired_times(f, g, pairs: int) -> tuple[list[float], list[float]]:
    """Times [s] of ``pairs`` alternating calls of f and g (after one warm-up call of each)."""
    f()  # warm caches (window, FFT plans) and, on the first run on a machine, compile
    g()
    tf, tg = [], []
    for _ in range(pairs):
        t0 = time.perf_counter()
        f()
        t1 = time.perf_counter()
        g()
        t2 = time.perf_counter()
        tf.append(t1 - t0)
        tg.append(t2 - t1)
    return tf, tg


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=60, help="pairs at 1024 px (scaled with the size)")
    ap.add_argument("--sizes", default="256,512,1024,2048,4096")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    print(f"{'size':>6} {'features ms':>12} {'rfft2 ms':>10} {'ratio':>6} {'(q25-q75)':>11} {'ms/MPx':>8} {'t/NlogN (rel)':>14} {'rfft2 t/NlogN':>14}")
    base = base_fft = None
    for n in (int(s) for s in args.sizes.split(",")):
        yy, xx = np.mgrid[0:n, 0:n]
        x = (0.5 + 0.3 * np.cos(2 * np.pi * (xx * 0.05 + yy * 0.02)) + 0.1 * rng.standard_normal((n, n)))
        x = np.clip(x, 0, 1).astype(np.float32)
        img = tz.load_image(x, dpi=300)
        pairs = max(7, min(args.repeat * 4, args.repeat * 1024 * 1024 // (n * n)))
        tf, tg = paired_times(lambda: tz.extract_features(img), lambda: scipy.fft.rfft2(x, workers=1), pairs)
        ratios = [a / b for a, b in zip(tf, tg)]
        q25, ratio, q75 = statistics.quantiles(ratios, n=4)
        t_feat, t_fft = statistics.median(tf), statistics.median(tg)
        nlogn = n * n * math.log2(n * n)
        base = base or t_feat / nlogn
        base_fft = base_fft or t_fft / nlogn
        print(
            f"{n:>6} {t_feat * 1e3:>12.2f} {t_fft * 1e3:>10.2f} {ratio:>6.2f} {f'({q25:.2f}-{q75:.2f})':>11}"
            f" {t_feat * 1e3 / (n * n / 1e6):>8.2f} {t_feat / nlogn / base:>14.2f} {t_fft / nlogn / base_fft:>14.2f}"
        )


if __name__ == "__main__":
    main()
