"""Benchmark: what the finger gets, for every preset, built-in texture and stroking speed.

For each preset, each built-in texture and each speed of 10, 20, 40, 60, 100 and
160 mm/s, the profile's drive is played on the simulated 75 um wire exactly as
``tactilize serve`` plays it (operating-point controller, closed loop, envelope,
on the ``aa-resistor`` circuit), and this reports:

* whether the wire follows (every pulse of the settled window has its own
  displacement peak of at least 0.5 um) and its per-pulse swing [um];
* the first felt pulse after pen-down, from standby and from cold [ms].

Reference, measured in the same run: the same drives with no controller, the
profile's own width (after its limits) at the rated 0.5 A into the relaxed wire
from a stiff voltage source, open loop, from cold, for 1.5 s.  It follows when
every pulse of its last third has its own displacement peak (at least 0.01 um)
and the median swing is at least 0.5 um; its first felt pulse is the end of the
first pulse with such a peak.  The ratio of the two counts of followed cells is
what the controller adds to the bare laws.

Run: python bench/bench_felt.py [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time

import tactilize as tz
from tactilize.actuators.felt import feel
from tactilize.actuators.sma import FOLLOW_THRESHOLD_M, Circuit, WireSpec, simulate_drive
from tactilize.mapping import preset_names
from tactilize.data import get_texture, texture_ids

SPEEDS_MM_S = (10, 20, 40, 60, 100, 160)


def uncontrolled(drive: tz.Drive, spec: WireSpec) -> tuple[bool, float]:
    """(follows, first felt pulse [ms]) of the drive with no controller: its own width at the
    rated current from a stiff source, open loop, from cold."""
    d = drive.replace(amplitude=1.0, strength=None)
    if d.is_off:
        return False, math.inf
    stiff = Circuit("stiff", "voltage", supply_v=spec.rated_current_a * spec.resistance_martensite_ohm, source_ohm=1e-9)
    res = simulate_drive(d, 1.5, spec, circuit=stiff, dt_s=1e-4)
    # Follows: every pulse of the last third has its own peak (0.01 um) and the median
    # swing is >= 0.5 um.
    rises = res.per_pulse_rise_m(1.0)
    swing = res.per_pulse_swing_m(1.0)
    follows = bool(rises.size) and bool((rises >= 0.01e-6).all()) and statistics.median(swing) >= FOLLOW_THRESHOLD_M
    all_rises = res.per_pulse_rise_m(0.0)
    hit = [i for i, r in enumerate(all_rises) if r >= 0.01e-6]
    first = (res.pulse_starts_s[hit[0]] + d.pulse_width_s) * 1e3 if hit else math.inf
    return follows, first


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON document")
    args = ap.parse_args()
    spec = WireSpec.preset("75um")
    feats = {tid: tz.extract_features(get_texture(tid).image) for tid in texture_ids()}
    rows = []
    t0 = time.perf_counter()
    for preset in preset_names():
        profile = tz.Profile.preset(preset)
        for tid, feat in feats.items():
            for v in SPEEDS_MM_S:
                drive = profile.drive(feat, v / 1e3)
                warm = feel(drive, spec)
                cold = feel(drive, spec, standby=False)
                ref_follows, ref_first = uncontrolled(drive, spec)
                rows.append({
                    "preset": preset, "texture": tid, "speed_mm_s": v,
                    "frequency_hz": drive.pulse_frequency_hz, "strength": drive.strength,
                    "follows": warm.follows, "displacement_pp_um": warm.displacement_pp_um,
                    "first_follow_standby_ms": warm.first_follow_ms, "first_follow_cold_ms": cold.first_follow_ms,
                    "peak_temperature_c": max(warm.peak_temperature_c, cold.peak_temperature_c),
                    "reference_follows": ref_follows, "reference_first_follow_ms": ref_first,
                })
    elapsed = time.perf_counter() - t0
    if args.json:
        print(json.dumps({"rows": rows, "seconds": elapsed}, default=lambda x: None if x == math.inf else x))
        return
    for preset in preset_names():
        sel = [r for r in rows if r["preset"] == preset]
        print(f"\npreset {preset}: follows (displacement p-p um) / first felt pulse from standby, from cold [ms]")
        print(f"  {'texture':10}" + "".join(f"{v:>19} mm/s" for v in SPEEDS_MM_S))
        for tid in feats:
            cells = []
            for r in (r for r in sel if r["texture"] == tid):
                mark = "Y" if r["follows"] else "n"
                cells.append(f"{mark} {r['displacement_pp_um']:5.2f} {r['first_follow_standby_ms']:5.1f} {r['first_follow_cold_ms']:5.1f}")
            print(f"  {tid:10}" + "".join(f"{c:>24}" for c in cells))
        n = len(sel)
        felt = sum(r["follows"] for r in sel)
        ref = sum(r["reference_follows"] for r in sel)
        fast = sum(r["first_follow_standby_ms"] <= 25 for r in sel)
        ref_first = [r["reference_first_follow_ms"] for r in sel]
        never = sum(x == math.inf for x in ref_first)
        ref_med = statistics.median(ref_first)  # inf counts as the slowest
        warm_med = statistics.median(r["first_follow_standby_ms"] for r in sel)
        cold_med = statistics.median(r["first_follow_cold_ms"] for r in sel)
        print(f"  followed: {felt}/{n} (reference, no controller: {ref}/{n}; ratio {felt / max(ref, 1):.2f})")
        print(f"  first felt pulse within 25 ms of pen-down from standby: {fast}/{n}")
        print(f"  median first felt pulse: {warm_med:.1f} ms from standby, {cold_med:.1f} ms from cold; "
              f"reference {ref_med:.0f} ms, {never}/{n} never in 1.5 s (ratio reference / standby {ref_med / warm_med:.0f})")
        cord = next((r for r in sel if r["texture"] == "corduroy" and r["speed_mm_s"] == 40), None)
        if cord is not None:
            print(f"  corduroy at 40 mm/s: first felt pulse {cord['first_follow_standby_ms']:.1f} ms from standby, "
                  f"{cord['first_follow_cold_ms']:.1f} ms from cold; reference {cord['reference_first_follow_ms']:.0f} ms")
        print(f"  highest temperature: {max(r['peak_temperature_c'] for r in sel):.1f} C (limit {spec.max_temperature_c:g} C)")
    print(f"\n({elapsed:.1f} s)")


if __name__ == "__main__":
    main()
