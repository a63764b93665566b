"""Benchmark: the voice coil's signal, run by ``bench_surfaces.py --only audio``.

1. The spectrum of the tip's acceleration (:mod:`tactilize.synthesis.acceleration`,
   what the WAV export carries) and of the event wavelets (what the sound card and
   the page play, :mod:`tactilize.synthesis.wavelets`), 48 kHz, 1 s straight strokes:

   * a 1 mm sinusoidal grating (0.26 mm pixels) at 20 .. 320 mm/s: the peak against
     v f_s, and the RMS against the v^2 law (relative to 40 mm/s);
   * sandpaper-like grains (jittered grid, mean pitch 0.5 .. 8 mm) at 100 mm/s: the
     spectral centroid, which should fall as the pitch rises;
   * a smooth curved ramp at 100 mm/s: power at speed / pixel pitch (385 Hz), ours
     against a bilinear lookup of the same height through the same filters [dB].

2. Cost of one second of signal, median of repeats, against references measured in
   the same run: the steady pulse train of one second (what the WAV held before), and
   the events of the same stroke (what the real-time path computes).

Run: python bench/bench_surfaces.py --only audio [--quick] [--json]
"""

from __future__ import annotations

import statistics
import time
from typing import Any, Callable

import numpy as np

from tactilize.drive import Drive
from tactilize.surface import stroke_events, surface_model
from tactilize.surface.fields import grain_field, grating_field
from tactilize.synthesis import pulse_train
from tactilize.synthesis.acceleration import (
    band_limited_acceleration,
    spectral_centroid_hz,
    spectral_peak_hz,
    spectrum,
    tip_acceleration,
)
from tactilize.synthesis.wavelets import event_wavelets, render_wavelets

RATE = 48_000.0
PIXEL_M = 0.26e-3
GRATING_PER_M = 1000.0
SPEEDS_MM_S = (20.0, 40.0, 80.0, 160.0, 320.0)
PITCHES_MM = (0.5, 1.0, 2.0, 4.0, 8.0)
GRAIN_SPEED_MM_S = 100.0


def _line(speed_m_s: float, duration_s: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(0.0, duration_s, 1 / 240)
    return t, 5e-3 + speed_m_s * t, np.full(t.size, 10e-3)


def _both(surface: Any, speed_m_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(acceleration, wavelets) of a 1 s stroke at ``speed_m_s``."""
    t, x, y = _line(speed_m_s)
    acc = tip_acceleration(surface, t, x, y, sample_rate_hz=RATE).samples
    wav = render_wavelets(event_wavelets(stroke_events(surface, t, x, y)), 0.0, int(RATE), RATE)
    return acc, wav


def gratings() -> list[dict[str, float]]:
    surface = surface_model(grating_field(GRATING_PER_M, 0.0, (0.4, 0.02), PIXEL_M), pitch_m=PIXEL_M)
    rows = []
    for v in SPEEDS_MM_S:
        acc, wav = _both(surface, v * 1e-3)
        rows.append({"speed_mm_s": v, "expected_hz": v * 1e-3 * GRATING_PER_M,
                     "peak_hz": spectral_peak_hz(*spectrum(acc, RATE)),
                     "wavelet_peak_hz": spectral_peak_hz(*spectrum(wav, RATE)),
                     "rms": float(np.sqrt(np.mean(acc[4800:-4800] ** 2)))})
    ref = next(r["rms"] for r in rows if r["speed_mm_s"] == 40.0)
    print(f"\n1 mm grating, 0.26 mm pixels: peak against v f_s; RMS against v^2 (from 40 mm/s)")
    print(f"{'mm/s':>6} {'v f_s Hz':>9} {'peak Hz':>8} {'wavelets':>9} {'RMS ratio':>10} {'v^2':>7}")
    for r in rows:
        r["rms_ratio"] = r["rms"] / ref
        r["v2_ratio"] = (r["speed_mm_s"] / 40.0) ** 2
        print(f"{r['speed_mm_s']:6.0f} {r['expected_hz']:9.1f} {r['peak_hz']:8.1f} {r['wavelet_peak_hz']:9.1f} "
              f"{r['rms_ratio']:10.3f} {r['v2_ratio']:7.3f}")
    return rows


def grains() -> list[dict[str, float]]:
    rows = []
    print(f"\ngrains (jittered grid) at {GRAIN_SPEED_MM_S:g} mm/s: spectral centroid (20 .. 1000 Hz)")
    print(f"{'pitch mm':>9} {'v/p Hz':>7} {'centroid':>9} {'wavelets':>9}")
    for p in PITCHES_MM:
        field = grain_field(p * 1e-3, (0.2, 0.03), px_per_pitch=8, seed=1)
        surface = surface_model(field.heights, pitch_m=field.pitch_m)
        acc, wav = _both(surface, GRAIN_SPEED_MM_S * 1e-3)
        r = {"pitch_mm": p, "speed_over_pitch_hz": GRAIN_SPEED_MM_S / p,
             "centroid_hz": spectral_centroid_hz(*spectrum(acc, RATE)),
             "wavelet_centroid_hz": spectral_centroid_hz(*spectrum(wav, RATE))}
        rows.append(r)
        print(f"{p:9.1f} {r['speed_over_pitch_hz']:7.1f} {r['centroid_hz']:9.1f} {r['wavelet_centroid_hz']:9.1f}")
    return rows


def pixel_tone() -> dict[str, float]:
    width = 0.1
    x = (np.arange(int(width / PIXEL_M)) + 0.5) * PIXEL_M
    surface = surface_model(np.tile(((x / width) ** 2).astype(np.float32), (40, 1)), pitch_m=PIXEL_M)
    v = 0.1
    t, xs, ys = _line(v, 0.8)
    ours = tip_acceleration(surface, t, xs, ys, sample_rate_hz=RATE).samples
    tt = np.arange(ours.size) / RATE
    bilinear = band_limited_acceleration(surface.sample(np.interp(tt, t, xs), np.interp(tt, t, ys)).astype(float), RATE)
    tone = v / PIXEL_M

    def power(a: np.ndarray) -> float:
        f, p = spectrum(a[4800:-4800], RATE)
        return float(p[(f > tone - 5) & (f < tone + 5)].sum())

    db = 10 * np.log10(max(power(ours), 1e-300) / power(bilinear))
    print(f"\nsmooth ramp at 100 mm/s: power at v / pixel pitch ({tone:.0f} Hz), ours against bilinear: {db:.0f} dB")
    return {"tone_hz": tone, "ours_over_bilinear_db": float(db)}


def _median_s(fn: Callable[[], Any], repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def costs(repeats: int) -> dict[str, float]:
    field = grain_field(1e-3, (0.2, 0.03), px_per_pitch=8, seed=1)
    surface = surface_model(field.heights, pitch_m=field.pitch_m)
    t, x, y = _line(0.04)
    drive = Drive(pulse_frequency_hz=40.0, pulse_width_s=1e-3, amplitude=1.0)
    events = stroke_events(surface, t, x, y)
    wl = event_wavelets(events)
    out = {
        "acceleration_s": _median_s(lambda: tip_acceleration(surface, t, x, y, sample_rate_hz=RATE), repeats),
        "wavelets_s": _median_s(lambda: render_wavelets(wl, 0.0, int(RATE), RATE), repeats),
        "pulse_train_s": _median_s(lambda: pulse_train(drive, 1.0, RATE), repeats),
        "events_s": _median_s(lambda: stroke_events(surface, t, x, y), repeats),
    }
    print(f"\none second of signal at 48 kHz (1 mm grains, 40 mm/s), median of {repeats}:")
    print(f"  tip acceleration   {out['acceleration_s'] * 1e3:7.2f} ms  = {out['acceleration_s'] / out['pulse_train_s']:6.1f}x "
          f"the steady pulse train ({out['pulse_train_s'] * 1e3:.2f} ms), "
          f"{out['acceleration_s'] / out['events_s']:.1f}x the stroke's events ({out['events_s'] * 1e3:.2f} ms)")
    print(f"  event wavelets     {out['wavelets_s'] * 1e3:7.2f} ms  = {out['wavelets_s'] / out['pulse_train_s']:6.1f}x "
          f"the steady pulse train")
    return out


def run(quick: bool = False) -> dict[str, Any]:
    """Every table and cost; the JSON-ready results."""
    return {"gratings": gratings(), "grains": grains(), "pixel_tone": pixel_tone(), "cost": costs(5 if quick else 21)}
