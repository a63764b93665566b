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
from .android_envelopes import ANDROID_LIMITS, envelopes, run_lengths
from .android_events import android_surface_document
from .timeline import (
    CONTROL_STEP_S,
    SHARPNESS_LOW_HZ,
    DriveTimeline,
    control_points,
    intensity_from_drive,
)

__all__ = ["android_document", "android_waveform", "ANDROID_LIMITS"]

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
    return run_lengths(level[:total_ms] if total_ms > 0 else level)


def android_document(tl: DriveTimeline, kind: str = "profile", channel: int = 0, step_s: float = CONTROL_STEP_S) -> dict[str, Any]:
    """The Android document of one channel of a timeline (see the module docstring)."""
    if tl.plays_events(kind):
        return android_surface_document(tl, step_s)
    pts = control_points(tl, kind, channel, step_s)
    flat, waveform, basic = envelopes(pts)
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
