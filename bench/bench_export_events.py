"""Benchmark: what the parametric exports carry of a surface stroke, against the true crossings.

A generated field of bumps 3 mm apart (raised cosines of 1 mm radius, centres known) is stroked straight through
its centres for 1.5 s at 20 .. 160 mm/s, and generated grains (1 mm mean pitch) at 20 .. 80 mm/s.  For each:

* the reference, measured in the same run: the true crossings (where the line passes each centre, in time);
* AHAP and .hjif transients as ratios of it, with the largest |transient - crossing| [ms];
* the continuous stretches (count, and seconds of the stroke they cover) where bumps come closer than the
  player's interval (20 ms for a phone's actuator, 22 ms for the MPEG synthesiser: docs/surfaces.md, "Exports");
* the export's cost: run_stroke plus the four documents, against run_stroke alone (its wire simulation).

Run: python bench/bench_export_events.py [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from tactilize.export import read_ahap, read_hjif, render, run_stroke, synthetic_stroke
from tactilize.export.events import HJIF_TRANSIENT_S, PHONE_TRANSIENT_S, plan_events
from tactilize.export.stroke import PREROLL_S
from tactilize.image import load_image
from tactilize.mapping import Profile
from tactilize.surface import surface_model
from tactilize.surface.fields import bump_field, grain_field
from tactilize.maps.texturemap import texture_map

PITCH_M = 1e-4
STROKE_S = 1.5
FORMATS = ("ahap", "android", "haptic", "hjif")


def _setup(heights, pitch_m, profile):
    img = load_image(heights, dpi=0.0254 / pitch_m)
    return texture_map(img), surface_model(img, tip_radius_m=profile.tip_radius_m)


def _stroke(tmap, surface, profile, v):
    stroke = synthetic_stroke(tmap.width_m, tmap.height_m, v, STROKE_S)
    t0 = time.perf_counter()
    tl = run_stroke(stroke, tmap, profile, start_s=0.0, end_s=STROKE_S, mirror=True, surface=surface)
    t1 = time.perf_counter()
    docs = {f: json.loads(render(tl, f)) for f in FORMATS}
    t2 = time.perf_counter()
    return tl, docs, (t2 - t0) / (t1 - t0)


def bumps_row(tmap, surface, profile, centres_x, width_m, v):
    tl, docs, cost = _stroke(tmap, surface, profile, v)
    true_t = (centres_x - width_m / 2) / v - PREROLL_S
    true_t = np.sort(true_t[(true_t > 0.005) & (true_t < STROKE_S - 0.005)])
    taps = np.sort([t.t_s for t in read_ahap(docs["ahap"]).taps])
    err = float(np.max(np.abs(taps - true_t))) * 1e3 if taps.size == true_t.size and taps.size else None
    runs = plan_events(tl.events, PHONE_TRANSIENT_S, tl.end_s).runs
    return {"speed_mm_s": v * 1e3, "crossings": int(true_t.size),
            "ahap_transients_per_crossing": taps.size / max(true_t.size, 1),
            "hjif_transients_per_crossing": len(read_hjif(docs["hjif"]).taps) / max(true_t.size, 1),
            "max_error_ms": err, "continuous_runs": len(runs),
            "continuous_s": round(sum(r.end_s - r.start_s for r in runs), 3), "cost_vs_run_stroke": round(cost, 2)}


def grains_row(tmap, surface, profile, v):
    tl, docs, cost = _stroke(tmap, surface, profile, v)
    phone = plan_events(tl.events, PHONE_TRANSIENT_S, tl.end_s)
    mpeg = plan_events(tl.events, HJIF_TRANSIENT_S, tl.end_s)
    return {"speed_mm_s": v * 1e3, "bumps": len(tl.events),
            "phone_transients_per_bump": len(phone.transients) / max(len(tl.events), 1),
            "hjif_transients_per_bump": len(mpeg.transients) / max(len(tl.events), 1),
            "phone_continuous_s": round(sum(r.end_s - r.start_s for r in phone.runs), 3),
            "cost_vs_run_stroke": round(cost, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    profile = Profile.preset("surface")
    size = (0.6, 0.02)
    xs = 0.3 + 0.0015 + 0.003 * np.arange(95)
    field = bump_field(np.stack([xs, np.full(xs.size, size[1] / 2)], 1), 1e-3, size, PITCH_M)
    tmap, surface = _setup(field.heights, PITCH_M, profile)
    bumps = [bumps_row(tmap, surface, profile, xs, size[0], v) for v in (0.02, 0.04, 0.08, 0.12, 0.16)]
    grains = grain_field(1e-3, (0.2, 0.02), seed=1)
    gmap, gsurface = _setup(grains.heights, grains.pitch_m, profile)
    grain_rows = [grains_row(gmap, gsurface, profile, v) for v in (0.02, 0.04, 0.08)]
    if args.json:
        print(json.dumps({"bumps_3mm": bumps, "grains_1mm": grain_rows}, indent=1))
        return
    print("bumps 3 mm apart, r 1 mm, 1.5 s strokes: transients per true crossing (reference: the crossings)")
    for r in bumps:
        err = "-" if r["max_error_ms"] is None else f"{r['max_error_ms']:.2f} ms"
        print(f"  {r['speed_mm_s']:5.0f} mm/s  crossings {r['crossings']:3d}  AHAP {r['ahap_transients_per_crossing']:.2f}x"
              f"  .hjif {r['hjif_transients_per_crossing']:.2f}x  max |dt| {err}  continuous {r['continuous_runs']}"
              f" ({r['continuous_s']:.2f} s)  cost {r['cost_vs_run_stroke']:.2f}x run_stroke")
    print("grains 1 mm mean pitch: transients per bump found")
    for r in grain_rows:
        print(f"  {r['speed_mm_s']:5.0f} mm/s  bumps {r['bumps']:3d}  phone {r['phone_transients_per_bump']:.2f}x"
              f"  .hjif {r['hjif_transients_per_bump']:.2f}x  phone continuous {r['phone_continuous_s']:.2f} s"
              f"  cost {r['cost_vs_run_stroke']:.2f}x run_stroke")


if __name__ == "__main__":
    main()
