"""Materials: every library material's voice-coil signal and events at 50, 100 and 200 mm/s.

    PYTHONPATH=src python bench/bench_materials.py [--json]

Each material is stroked on a generated picture of its kind (grains of its size, brushed
streaks, ribs, a weave, fibres, or a flat sheet), photographed under uneven light (a
gradient and vignetting), shown 50 mm wide, straight along x for 1 s, with the library
material named (docs/surfaces.md, "Materials").  Printed per material and speed: the
tip's acceleration RMS [m/s^2, dB re 1 m/s^2], its spectral centroid [Hz], how far above
the detection threshold it is, and the events per second.  Then checks against published
facts (docs/references.md, section 11 (checks on the library)):

- coarser sandpaper is louder (P80 over P240; Bensmaia and Hollins 2003 and 2005);
- the level grows with speed, and the centroid and event rate rise with it
  (Bensmaia and Hollins 2003; kinematics, docs/references.md, section 3 (stylus on a natural surface));
- the six materials of the reference recordings in their order: the brushed metal the quietest and
  the granite the loudest at 170-250 mm/s, beside the picture alone on the same pictures;
- smooth materials (polished metal and stone, glass, smooth plastic) are under the
  detection threshold.

No recordings are held here: the 3 dB goal cannot be checked, only orderings and spans.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
from scipy.ndimage import gaussian_filter

from tactilize.materials import library, sensation_ratio
from tactilize.surface import surface_model
from tactilize.surface import stroke_events
from tactilize.surface.straight import MirroredSurface
from tactilize.synthesis.acceleration import spectral_centroid_hz, spectrum, tip_acceleration

N = 512
WIDTH_M = 50e-3
PITCH_M = WIDTH_M / N
FS = 48_000.0
SPEEDS_MM_S = (50.0, 100.0, 200.0)
RECORDED = ("metal-brushed", "leather-grained", "wood-sanded", "paper-kraft", "fabric-knit", "stone-granite")
SMOOTH = ("metal-polished", "glass", "plastic-smooth", "stone-polished")


def _norm(a: np.ndarray) -> np.ndarray:
    return (a - a.min()) / max(float(a.max() - a.min()), 1e-12)


def _grains(rng, size_m: float) -> np.ndarray:
    return _norm(gaussian_filter(rng.standard_normal((N, N)), max(0.5, 0.35 * size_m / PITCH_M)))


def _streaks(rng) -> np.ndarray:  # brushed along y: stroked across the brushing
    return _norm(gaussian_filter(rng.standard_normal((N, N)), (30.0, 0.7)))


def _ribs(rng, pitch_m: float) -> np.ndarray:
    x = np.arange(N) * PITCH_M
    ribs = 0.5 + 0.5 * np.cos(2 * math.pi * x / pitch_m)
    return _norm(np.tile(ribs, (N, 1)) + 0.2 * _grains(rng, 0.3e-3))


def _weave(rng, pitch_m: float) -> np.ndarray:
    yy, xx = np.mgrid[0:N, 0:N] * PITCH_M
    w = np.cos(2 * math.pi * xx / pitch_m) * np.cos(2 * math.pi * yy / pitch_m)
    return _norm(w + 0.3 * _grains(rng, 0.2e-3))


def _fibres(rng) -> np.ndarray:
    return _norm(gaussian_filter(rng.standard_normal((N, N)), (1.0, 4.0)) + 0.5 * _grains(rng, 0.3e-3))


def _flat(rng) -> np.ndarray:
    return np.full((N, N), 0.5) + 0.01 * rng.standard_normal((N, N))


#: The picture of each kind of material (what a photograph of it would mostly show).
KIND = {
    "metal-polished": _flat, "glass": _flat, "plastic-smooth": _flat, "stone-polished": _flat,
    "metal-brushed": _streaks,
    "plastic-textured": lambda r: _grains(r, 0.3e-3),
    "paper-printer": _fibres, "paper-kraft": _fibres, "cardboard": _fibres,
    "wood-sanded": lambda r: _norm(_streaks(r).T + 0.5 * _fibres(r)), "wood-raw": lambda r: _norm(_streaks(r).T),
    "stone-granite": lambda r: _grains(r, 2e-3), "stone-sandstone": lambda r: _grains(r, 0.4e-3),
    "fabric-silk": lambda r: _weave(r, 0.3e-3), "fabric-woven": lambda r: _weave(r, 0.8e-3),
    "fabric-knit": lambda r: _ribs(r, 2e-3), "fabric-denim": lambda r: _weave(r, 1.0e-3),
    "fabric-corduroy": lambda r: _ribs(r, 3e-3), "fabric-fleece": lambda r: _grains(r, 1.5e-3),
    "leather-smooth": lambda r: _grains(r, 0.5e-3), "leather-grained": lambda r: _grains(r, 1.5e-3),
    "rubber": lambda r: _grains(r, 0.3e-3), "cork": lambda r: _grains(r, 2e-3),
    "sandpaper-p80": lambda r: _grains(r, 201e-6 * 2), "sandpaper-p240": lambda r: _grains(r, 58.5e-6 * 2),
}


def photograph(name: str, seed: int = 7) -> np.ndarray:
    """The material's picture under uneven light: 30 % gradient and vignetting over its texture."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:N, 0:N] / N - 0.5
    light = 0.3 * (xx + 0.5) - 0.6 * (xx ** 2 + yy ** 2)
    return np.clip(0.2 + 0.6 * KIND[name](rng) + light, 0.0, 1.0).astype(np.float32)


def measure(surface, speed_mm_s: float, duration_s: float = 1.0) -> dict[str, float]:
    v = speed_mm_s * 1e-3
    t = np.arange(-0.1, duration_s + 0.1, 1 / 240.0)
    x, y = 5e-3 + v * t, np.full(t.size, 0.5 * WIDTH_M)
    sig = tip_acceleration(MirroredSurface(surface), t, x, y, sample_rate_hz=FS, start_s=0.0, end_s=duration_s)
    f, p = spectrum(sig)
    rms = float(np.sqrt(np.mean(sig.samples ** 2)))
    inside = x <= surface.width_m  # events on the picture itself (no mirror), per second of it
    events = [e for e in stroke_events(surface, t[inside], x[inside], y[inside]) if e.t_s >= 0.0]
    on_s = min(duration_s, (surface.width_m - 5e-3) / v)
    return {"rms": rms, "db": 20 * math.log10(max(rms, 1e-30)), "centroid_hz": spectral_centroid_hz(f, p),
            "sensation": sensation_ratio(sig.samples, FS), "events_per_s": len(events) / on_s}


def main() -> int:
    as_json = "--json" in sys.argv
    rows: dict[str, dict[float, dict[str, float]]] = {}
    for name in library():
        s = surface_model(photograph(name), pitch_m=PITCH_M, material=name)
        rows[name] = {v: measure(s, v) for v in SPEEDS_MM_S}
    # The six recorded materials at the recordings' speeds, with the material and the picture alone.
    recorded = {}
    for name in RECORDED:
        img = photograph(name)
        with_m = surface_model(img, pitch_m=PITCH_M, material=name)
        alone = surface_model(img, pitch_m=PITCH_M)
        recorded[name] = {
            "material_db": float(np.mean([measure(with_m, v)["db"] for v in (170.0, 210.0, 250.0)])),
            "picture_db": float(np.mean([measure(alone, v)["db"] for v in (170.0, 210.0, 250.0)])),
        }
    checks = _checks(rows, recorded)
    if as_json:
        print(json.dumps({"rows": {k: {str(v): r for v, r in d.items()} for k, d in rows.items()},
                          "recorded": recorded, "checks": checks}))
        return 0 if all(c["ok"] for c in checks) else 1
    print(f"{'material':<17}" + "".join(f" | {v:>3.0f} mm/s: m/s^2    dB  centroid  xthr  ev/s" for v in SPEEDS_MM_S))
    for name, by in rows.items():
        print(f"{name:<17}" + "".join(
            f" | {r['rms']:>14.3g} {r['db']:>5.1f} {r['centroid_hz']:>7.0f} Hz {r['sensation']:>5.2g} {r['events_per_s']:>5.0f}"
            for r in by.values()))
    print("\nThe six recorded materials, 170-250 mm/s (dB re 1 m/s^2; the picture alone in dB re its own units):")
    top_m = max(r["material_db"] for r in recorded.values())
    top_p = max(r["picture_db"] for r in recorded.values())
    for name, r in recorded.items():
        print(f"  {name:<17} material {r['material_db'] - top_m:>6.1f} dB   picture alone {r['picture_db'] - top_p:>6.1f} dB")
    print()
    for c in checks:
        print(f"  [{'ok' if c['ok'] else 'FAIL'}] {c['check']}: {c['detail']}")
    return 0 if all(c["ok"] for c in checks) else 1


def _checks(rows, recorded) -> list[dict[str, object]]:
    out: list[dict[str, object]] = []

    def check(text: str, ok: bool, detail: str) -> None:
        out.append({"check": text, "ok": bool(ok), "detail": detail})

    d = [rows["sandpaper-p80"][v]["db"] - rows["sandpaper-p240"][v]["db"] for v in SPEEDS_MM_S]
    check("coarser sandpaper is louder (Bensmaia and Hollins 2003, 2005)", min(d) > 0,
          "P80 - P240 = " + ", ".join(f"{x:+.1f} dB" for x in d) + " at 50/100/200 mm/s")
    felt = [n for n, by in rows.items() if by[100.0]["sensation"] >= 1.0]
    grow = [n for n in felt if rows[n][50.0]["db"] < rows[n][100.0]["db"] < rows[n][200.0]["db"]]
    per_doubling = np.median([(rows[n][200.0]["db"] - rows[n][50.0]["db"]) / 2 for n in felt])
    check("level grows with speed (Bensmaia and Hollins 2003)", len(grow) == len(felt),
          f"{len(grow)} of {len(felt)} felt materials; median {per_doubling:.1f} dB per doubling of speed")
    rise = [n for n in felt if rows[n][50.0]["centroid_hz"] < rows[n][200.0]["centroid_hz"]]
    # Coarse ribs and pile put their crossing rate below the band's 20 Hz at 50 mm/s, where only
    # their harmonics and the micro-roughness are left: the centroid then need not rise.
    check("spectral centroid rises with speed (kinematics), for at least 80 % of the felt materials",
          len(rise) >= 0.8 * len(felt),
          f"{len(rise)} of {len(felt)}; not: {', '.join(sorted(set(felt) - set(rise))) or 'none'}")
    more = [n for n in felt if rows[n][50.0]["events_per_s"] < rows[n][200.0]["events_per_s"]]
    check("events per second rise with speed (kinematics)", len(more) == len(felt), f"{len(more)} of {len(felt)}")
    order = sorted(recorded, key=lambda n: recorded[n]["material_db"])
    span = recorded[order[-1]]["material_db"] - recorded[order[0]]["material_db"]
    alone = sorted(recorded, key=lambda n: recorded[n]["picture_db"])
    span_alone = recorded[alone[-1]]["picture_db"] - recorded[alone[0]]["picture_db"]
    check("brushed metal the quietest and granite the loudest of the six recorded (the reference recordings)",
          order[0] == "metal-brushed" and order[-1] == "stone-granite",
          f"order {', '.join(order)}; span {span:.1f} dB (recorded: 32 dB); picture alone: {', '.join(alone)}, "
          f"span {span_alone:.1f} dB")
    silent = [n for n in SMOOTH if rows[n][200.0]["sensation"] < 1.0]
    check("smooth materials are under the detection threshold at 200 mm/s (section 11)",
          len(silent) == len(SMOOTH), f"{len(silent)} of {len(SMOOTH)}: " +
          ", ".join(f"{n} {rows[n][200.0]['sensation']:.2g}x" for n in SMOOTH))
    return out


if __name__ == "__main__":
    sys.exit(main())
