"""Android envelopes shared by the stroke documents and the bumps' compositions.

The limits an Android device promises for envelopes, control points as the
API 36 envelopes (:func:`envelopes`) and a level per millisecond as
``createWaveform`` timings (:func:`run_lengths`); :mod:`.android` and
:mod:`.android_events` build their documents from them (docs/references.md,
section 6 (Android envelopes) and (Android waveform)).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .timeline import SHARPNESS_LOW_HZ, ControlPoint, sharpness_from_frequency

__all__ = ["ANDROID_LIMITS", "MAX_CONTROL_POINTS", "MAX_SEGMENT_MS", "MIN_SEGMENT_MS", "envelopes", "run_lengths"]

#: Shortest and longest envelope segment [ms], most control points per envelope.
MIN_SEGMENT_MS = 20
MAX_SEGMENT_MS = 1000
MAX_CONTROL_POINTS = 16

#: The documented limits the envelopes are built within.
ANDROID_LIMITS: dict[str, Any] = {
    "min_segment_ms": MIN_SEGMENT_MS,
    "max_segment_ms": MAX_SEGMENT_MS,
    "max_control_points": MAX_CONTROL_POINTS,
    "amplitude_range": [0.0, 1.0],
    "basic_envelope_starts_and_ends_at_zero": True,
    "source": "docs/references.md, section 6 (Android envelopes)",
}


def run_lengths(level: np.ndarray) -> tuple[list[int], list[int]]:
    """createWaveform timings [ms] and amplitudes of a level per millisecond."""
    edges = np.flatnonzero(np.diff(level)) + 1
    starts = np.concatenate(([0], edges))
    ends = np.concatenate((edges, [level.size]))
    return [int(e - s) for s, e in zip(starts, ends)], [int(level[s]) for s in starts]


def _pieces(points: list[dict[str, Any]], n: int) -> list[list[dict[str, Any]]]:
    return [points[i : i + n] for i in range(0, len(points), n)] or [[]]


def _silent_frequencies(pts: list[ControlPoint]) -> list[ControlPoint]:
    """Points where the drive is off (0 Hz) take the frequency of the nearest point that is on.

    An envelope's frequencies must be above 0 Hz; at amplitude 0 the frequency
    plays nothing, so the neighbour's keeps the ramps between points short.
    """
    on = [p.frequency_hz for p in pts if p.frequency_hz > 0]
    if len(on) == len(pts):
        return pts
    f = on[0] if on else SHARPNESS_LOW_HZ
    out = []
    for p in pts:
        if p.frequency_hz > 0:
            f = p.frequency_hz
        out.append(p if p.frequency_hz > 0 else ControlPoint(p.t_s, p.amplitude, f))
    return out


def envelopes(pts: list[ControlPoint]) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[dict[str, Any]]]:
    """Control points as the flat list, the waveform envelopes and the basic envelopes (module docstring)."""
    pts = _silent_frequencies(pts)
    # Segments in whole ms, measured between rounded times so they never drift.
    ms = [int(round(p.t_s * 1e3)) for p in pts]
    flat = [
        {"amplitude": round(p.amplitude, 4), "frequency_hz": round(p.frequency_hz, 3), "duration_ms": ms[i] - ms[i - 1]}
        for i, p in enumerate(pts)
        if i > 0
    ]
    if len(pts) == 1 or (flat and all(f["duration_ms"] == 0 for f in flat)):
        flat = [{"amplitude": round(pts[0].amplitude, 4), "frequency_hz": round(pts[0].frequency_hz, 3),
                 "duration_ms": max(ms[-1] - ms[0], 1)}]
    per = MAX_CONTROL_POINTS
    waveform = []
    f0 = pts[0].frequency_hz
    for piece in _pieces(flat, per):
        waveform.append({"initial_frequency_hz": round(f0, 3), "control_points": piece})
        if piece:
            f0 = piece[-1]["frequency_hz"]
    basic = []
    for piece in _pieces(flat, per - 1):
        cps = [{"intensity": c["amplitude"], "sharpness": round(sharpness_from_frequency(c["frequency_hz"]), 4),
                "duration_ms": c["duration_ms"]} for c in piece]
        if cps:
            # ...and back to zero over the shortest segment allowed.
            cps.append({"intensity": 0.0, "sharpness": cps[-1]["sharpness"], "duration_ms": MIN_SEGMENT_MS})
        basic.append({"initial_sharpness": cps[0]["sharpness"] if cps else 0.0, "control_points": cps})
    return flat, waveform, basic
