"""Server work per pen batch: :meth:`PenRenderer.feed` for every preset, on the simulated wire.

What a user meets is the page's event-to-drive time; the renderer's work per batch is
the server's share of it.  Sandpaper at 40 mm/s, 4 ms batches of one 240 Hz sample
(the page's rhythm), 3000 batches per preset after 100 of warm-up, the wire's thread
running as in ``serve``.  Prints p50 / p99 / max [us] per preset.

Usage::

    python bench/bench_pen_batch.py [--batches N] [--json]

No assertion on wall-clock time: figures are printed.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def measure(preset: str, batches: int) -> dict[str, float]:
    from tactilize.actuators.simulated import SimulatedOutput
    from tactilize.data import get_texture
    from tactilize.maps.texturemap import texture_map
    from tactilize.mapping import Profile
    from tactilize.pen.renderer import PenRenderer
    from tactilize.pen.samples import PenSample
    from tactilize.surface import surface_model

    img = get_texture("sandpaper").image
    tmap = texture_map(img)
    profile = Profile.preset(preset)
    surface = surface_model(img, tip_radius_m=getattr(profile, "tip_radius_m", 0.25e-3))
    out = SimulatedOutput()
    try:
        r = PenRenderer(tmap, profile, out, surface=surface)
        v, y = 0.04, tmap.height_m / 2
        span = tmap.width_m - 4e-3
        took: list[float] = []
        t0 = time.monotonic()
        for k in range(batches + 100):
            t = k * 0.004
            x = 2e-3 + (v * t) % span
            if k and x < 2e-3 + v * 0.004:
                r.lift()
            while time.monotonic() - t0 < t:  # batches at the page's pace, so the wire's thread runs between
                time.sleep(0.0005)
            a = time.perf_counter_ns()
            r.feed([PenSample(t, x, y, 0.5)])
            b = time.perf_counter_ns()
            if k >= 100:
                took.append((b - a) / 1e3)
        r.lift()
    finally:
        out.close()
    us = np.array(took)
    return {"p50_us": float(np.percentile(us, 50)), "p99_us": float(np.percentile(us, 99)), "max_us": float(us.max())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", type=int, default=3000)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    rows = {p: measure(p, a.batches) for p in ("paper", "perceptual", "physical", "surface")}
    if a.json:
        print(json.dumps(rows))
        return
    for p, m in rows.items():
        print(f"{p:11s} p50 {m['p50_us']:7.1f} us   p99 {m['p99_us']:7.1f} us   max {m['max_us']:8.1f} us")


if __name__ == "__main__":
    main()
