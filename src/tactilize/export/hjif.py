"""MPEG-I Haptics (ISO/IEC 23090-31) in its JSON form, ``.hjif``, following a stroke.

Field names and structure as docs/references.md, section 6 (MPEG-I Haptics)
gives them: the root's ``version``, ``profile``, ``level``, ``date``,
``description``, ``timescale``, ``avatars``, ``perceptions``, ``syncs``; one
Vibrotactile perception; one channel per actuator (the pen's two); in each,

* a ``VectorialWave`` band whose ``Basis`` effects (one per run of events closer
  than 22 ms, split so no keyframe lies more than :data:`HJIF_MAX_EFFECT_TICKS`
  after its effect) carry keyframes of ``relative_position`` [ticks],
  ``amplitude_modulation`` (0..1) and ``frequency_modulation`` [Hz, the events'
  rate] on the 20 ms grid, on a ``Sine`` base signal;
* a ``Transient`` band with one effect per event at least 22 ms from its
  neighbours (the reference synthesiser's transient lasts 22 ms, so closer taps
  would overlap and smear), its keyframe the event's intensity and own frequency
  [Hz, at least 1].

One document for every rendering: the events are the stroke's
(:func:`~.events.timeline_events`: the bumps a stroke over a surface crossed, or
the pulses of a steady drive's train).

Every document keeps the rules of :mod:`.conformance.hjif` (the MPEG reference
reader's): ``frequency_modulation`` is a whole number of hertz (the reader
drops any other number, and a band without a frequency plays silence); the
avatar and the reference device have id 1 (0 is reserved); times are integer
ticks of ``timescale`` = 1000 per second (1 ms); band frequency limits are
integers [Hz].  The reference device describes the actuator the drive was made
for: its frequency range from the profile's limits.

References
----------
.. [1] docs/references.md, section 6 (MPEG-I Haptics).
.. [2] docs/references.md, section 6 (MPEG-I reader rules).
"""

from __future__ import annotations

import datetime as _dt
import math
from functools import partial
from typing import Any, Callable

from .events import HJIF_TRANSIENT_S, event_intensity, plan_events, run_points, timeline_events
from .timeline import CONTROL_STEP_S, DriveTimeline

__all__ = ["hjif_document", "HJIF_TIMESCALE", "HJIF_VERSION", "HJIF_MAX_EFFECT_TICKS"]

#: Ticks per second (the format's default; the reference synthesiser's phase assumes it).
HJIF_TIMESCALE = 1000
#: The edition written: the one the MPEG reference software writes (any year from 2023 is read).
HJIF_VERSION = "2023"
#: A keyframe's ``relative_position`` is 16 bits in the binary form: effects are split before it.
HJIF_MAX_EFFECT_TICKS = 60_000
#: The avatar, and the actuator's reference device (id 0 is reserved for "unspecified").
_AVATAR_ID = 1
_DEVICE_ID = 1


def _ticks(t_s: float) -> int:
    return int(round(t_s * HJIF_TIMESCALE))


def _hz(f: float) -> int:
    """A frequency as the reader takes it: a whole number of hertz."""
    return int(round(f))


def _band_limits(freqs: list[int]) -> tuple[int, int]:
    if not freqs:
        return 0, 1
    return min(freqs), max(max(freqs), min(freqs) + 1)


def _pieces(a: float, b: float) -> list[tuple[float, float]]:
    """``(start, end)`` [s] of a run cut so that no piece is longer than :data:`HJIF_MAX_EFFECT_TICKS`."""
    step = HJIF_MAX_EFFECT_TICKS / HJIF_TIMESCALE
    n = max(1, math.ceil((b - a) / step - 1e-9))
    edges = [a + (b - a) * k / n for k in range(n + 1)]
    return list(zip(edges, edges[1:]))


def _keyframes(pts: list[Any], pos: int) -> list[dict[str, Any]]:
    """Keyframes at whole ticks from ``pos``; of points that round to one tick, the first stays."""
    out: list[dict[str, Any]] = []
    for p in pts:
        rel = _ticks(p.t_s) - pos
        if out and rel <= out[-1]["relative_position"]:
            continue
        out.append({"relative_position": rel, "amplitude_modulation": round(p.amplitude, 4),
                    "frequency_modulation": _hz(p.frequency_hz)})
    return out


def _channel(tl: DriveTimeline, kind: str, c: int, step_s: float) -> dict[str, Any]:
    effects: list[dict[str, Any]] = []
    freqs: list[int] = []

    def wave(a0: float, b0: float, points: Callable[[float, float], list[Any]]) -> None:
        for a, b in _pieces(a0, b0):
            pos = _ticks(a)
            keyframes = _keyframes(points(a, b), pos)
            effects.append({"id": len(effects), "effect_type": "Basis", "position": pos, "phase": 0.0,
                            "base_signal": "Sine", "keyframes": keyframes})
            freqs.extend(k["frequency_modulation"] for k in keyframes)

    taps: list[dict[str, Any]] = []
    tap_f: list[int] = []

    def tap(t_s: float, amplitude: float, f: float) -> None:
        taps.append({
            "id": len(taps),
            "effect_type": "Basis",
            "position": _ticks(t_s),
            "phase": 0.0,
            "base_signal": "Sine",
            "keyframes": [{"relative_position": 0, "amplitude_modulation": round(amplitude, 4),
                           "frequency_modulation": _hz(f)}],
        })
        tap_f.append(_hz(f))

    # A transient per event the reference synthesiser plays apart, a wave where they come closer
    # (one rule for a stroke's bumps and a steady drive's pulses: .events.timeline_events).
    plan = plan_events(timeline_events(tl, kind, c), HJIF_TRANSIENT_S, tl.end_s)
    for r in plan.runs:
        wave(r.start_s, r.end_s, partial(run_points, r, step_s=step_s))
    for ev in plan.transients:
        tap(ev.t_s, event_intensity(ev.strength), max(ev.frequency_hz, 1.0))
    bands = []
    if effects:
        lo, hi = _band_limits(freqs)
        bands.append({"band_type": "VectorialWave", "lower_frequency_limit": lo, "upper_frequency_limit": hi,
                      "effects": effects})
    if taps:
        lo, hi = _band_limits(tap_f)
        bands.append({"band_type": "Transient", "lower_frequency_limit": lo, "upper_frequency_limit": hi,
                      "effects": taps})
    return {
        "id": c,
        "description": f"actuator {c + 1} of the pen",
        "reference_device_id": _DEVICE_ID,
        "gain": 1.0,
        "mixing_coefficient": 1.0,
        "body_part_mask": 0,
        "bands": bands,
    }


def hjif_document(tl: DriveTimeline, kind: str = "profile", step_s: float = CONTROL_STEP_S) -> dict[str, Any]:
    """The ``.hjif`` document of every channel of a timeline (see the module docstring)."""
    freqs = [d.pulse_frequency_hz for row in tl._rows(kind) for d in row if not d.is_off]
    lo_hz = tl.meta.get("min_frequency_hz", min(freqs) if freqs else 0.0)
    hi_hz = tl.meta.get("max_frequency_hz", max(freqs) if freqs else 1.0)
    what = f"events of the {kind}"
    desc = f"tactilize: {what} of a stroke of {tl.end_s:g} s"
    if tl.meta.get("image"):
        desc += f" on {tl.meta['image']}"
    return {
        "version": HJIF_VERSION,
        "profile": "Main",
        "level": 1,
        "date": _dt.date.today().isoformat(),
        "description": desc,
        "timescale": HJIF_TIMESCALE,
        "avatars": [{"id": _AVATAR_ID, "lod": 0, "type": "Vibration"}],
        "perceptions": [
            {
                "id": 0,
                "avatar_id": _AVATAR_ID,
                "description": "texture under the pen",
                "perception_modality": "Vibrotactile",
                "effect_library": [],
                "reference_devices": [
                    {"id": _DEVICE_ID, "name": str(tl.meta.get("actuator", "tactile pen actuator")), "body_part_mask": 0,
                     "minimum_frequency": float(min(lo_hz, hi_hz)), "maximum_frequency": float(max(lo_hz, hi_hz)),
                     "type": "Unknown"}
                ],
                "channels": [_channel(tl, kind, c, step_s) for c in range(tl.channels)],
            }
        ],
        "syncs": [],
    }
