"""Android vibration that follows a stroke: API 36 envelopes and the ``createWaveform`` fallback.

One JSON document a developer pastes in (docs/references.md, section 6
(Android waveform) and (Android envelopes)):

``waveform_envelopes``
    For ``VibrationEffect.WaveformEnvelopeBuilder`` (API 36): a list of
    envelopes, each ``initial_frequency_hz`` and at most 16 control points
    ``(amplitude 0..1, frequency_hz, duration_ms)``, every segment 20 ms .. 1 s
    (the limits a device promises).  A point's duration is the ramp from the
    point before; the first envelope ramps up from zero amplitude over its first
    segment.  Play them one after another.  Frequencies outside the device's
    ``getFrequencyProfile()`` are not played: below 65 Hz the fallback's taps
    carry the texture.
``basic_envelopes``
    The same over ``BasicEnvelopeBuilder`` (intensity 0..1, sharpness 0..1),
    each starting and ending at intensity 0, as that builder requires.
``timings_ms``, ``amplitudes``, ``repeat``
    ``VibrationEffect.createWaveform(timings, amplitudes, repeat)`` (API 26):
    below 65 Hz each pulse and gap in whole milliseconds (edges rounded from the
    exact times, so the pattern does not drift); at 65 Hz and above the
    intensity as a level 0..255 held while the drive holds (the motor supplies
    the frequency).
``envelope``
    Every waveform control point in one flat list (older readers).
``kotlin``
    A short snippet that builds the effects.

A stroke over a surface (``tl.events``) gets the bumps instead, in
compositions of primitives and envelopes played at their times
(:mod:`.android_events`).

References
----------
.. [1] docs/references.md, section 6 (Android waveform).
.. [2] docs/references.md, section 6 (Android envelopes).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..drive import Drive
from .timeline import (
    CONTROL_STEP_S,
    SHARPNESS_LOW_HZ,
    ControlPoint,
    DriveTimeline,
    control_points,
    intensity_from_drive,
    sharpness_from_frequency,
)

__all__ = ["android_document", "android_waveform", "ANDROID_LIMITS"]

#: The documented limits the envelopes are built within.
ANDROID_LIMITS = {
    "min_segment_ms": 20,
    "max_segment_ms": 1000,
    "max_control_points": 16,
    "amplitude_range": [0.0, 1.0],
    "basic_envelope_starts_and_ends_at_zero": True,
    "source": "docs/references.md, section 6 (Android envelopes)",
}


def _fallback(tl: DriveTimeline, kind: str, channel: int) -> tuple[list[int], list[int]]:
    """createWaveform timings and amplitudes at 1 ms resolution, run-length coded."""
    total_ms = int(round(tl.end_s * 1e3))
    level = np.zeros(max(total_ms, 1), dtype=np.int32)
    drives = tl.drives(kind, channel)
    bounds = [int(round(t * 1e3)) for t in tl.t_s] + [total_ms]
    for i, d in enumerate(drives):
        if not d.is_off and d.pulse_frequency_hz >= SHARPNESS_LOW_HZ:
            level[bounds[i] : bounds[i + 1]] = int(round(255 * intensity_from_drive(d)))
    for p in tl.pulses(kind, channel):
        if p.drive.pulse_frequency_hz < SHARPNESS_LOW_HZ:
            s = int(round(p.t_s * 1e3))
            # A pulse shorter than 1 ms still plays for 1 ms: the finest Android allows.
            e = max(s + 1, int(round((p.t_s + p.width_s) * 1e3)))
            level[s : min(e, total_ms)] = max(1, int(round(255 * p.amplitude)))
    return _run_lengths(level[:total_ms] if total_ms > 0 else level)


def _run_lengths(level: np.ndarray) -> tuple[list[int], list[int]]:
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


def _envelopes(pts: list[ControlPoint]) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[dict[str, Any]]]:
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
    per = ANDROID_LIMITS["max_control_points"]
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
            cps.append({"intensity": 0.0, "sharpness": cps[-1]["sharpness"], "duration_ms": ANDROID_LIMITS["min_segment_ms"]})
        basic.append({"initial_sharpness": cps[0]["sharpness"] if cps else 0.0, "control_points": cps})
    return flat, waveform, basic


def android_document(tl: DriveTimeline, kind: str = "profile", channel: int = 0, step_s: float = CONTROL_STEP_S) -> dict[str, Any]:
    """The Android document of one channel of a timeline (see the module docstring)."""
    if tl.plays_events(kind):
        from .android_events import android_surface_document

        return android_surface_document(tl, step_s)
    pts = control_points(tl, kind, channel, step_s)
    flat, waveform, basic = _envelopes(pts)
    timings, amps = _fallback(tl, kind, channel)
    return {
        "timings_ms": timings,
        "amplitudes": amps,
        "repeat": -1,
        "envelope": flat,
        "waveform_envelopes": waveform,
        "basic_envelopes": basic,
        "limits": ANDROID_LIMITS,
        "duration_ms": int(round(tl.end_s * 1e3)),
        "drive": tl.drives(kind, channel)[0].to_dict(),
        "kotlin": _kotlin(waveform),
    }


def _kotlin(waveform: list[dict[str, Any]]) -> str:
    lines = [
        "// API 36 and later; older devices: VibrationEffect.createWaveform(timings_ms, amplitudes, -1)",
        "val effects = listOf(",
    ]
    for env in waveform[:2]:
        lines.append(f"    VibrationEffect.WaveformEnvelopeBuilder().setInitialFrequencyHz({env['initial_frequency_hz']}f)")
        for c in env["control_points"][:3]:
            lines.append(f"        .addControlPoint({c['amplitude']}f, {c['frequency_hz']}f, {c['duration_ms']}L)")
        if len(env["control_points"]) > 3:
            lines.append("        // ... the rest of this envelope's control_points")
        lines.append("        .build(),")
    if len(waveform) > 2:
        lines.append("    // ... one builder per entry of waveform_envelopes")
    lines += [")", "effects.forEach { vibrator.vibrate(it) }  // one after another (each waits its length)"]
    return "\n".join(lines)


def android_waveform(drive: Drive, duration_s: float = 2.0) -> dict[str, Any]:
    """The Android document of one steady drive held for ``duration_s`` [s]."""
    return android_document(DriveTimeline.steady(drive, duration_s))
