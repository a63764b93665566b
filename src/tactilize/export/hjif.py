"""MPEG-I Haptics (ISO/IEC 23090-31) in its JSON form, ``.hjif``, following a stroke.

Field names and structure as docs/references.md, section 6 (MPEG-I Haptics)
gives them: the root's ``version``, ``profile``, ``level``, ``date``,
``description``, ``timescale``, ``avatars``, ``perceptions``, ``syncs``; one
Vibrotactile perception; one channel per actuator (the pen's two); in each,

* a ``VectorialWave`` band whose ``Basis`` effects (one per run of the stroke
  at 65 Hz and above) carry keyframes of ``relative_position`` [ticks],
  ``amplitude_modulation`` (0..1) and ``frequency_modulation`` [Hz] over the
  stroke, on a ``Sine`` base signal;
* a ``Transient`` band with one effect per pulse where the train is slower
  (the taps), its keyframe carrying the tap's amplitude and the train's
  pulse frequency [Hz].

Times are integer ticks of ``timescale`` = 1000 per second (1 ms).  Band
frequency limits are integers [Hz].  The reference device describes the
actuator the drive was made for: its frequency range from the profile's limits.
Its field names (``id``, ``name``, ``body_part_mask``, ``minimum_frequency``,
``maximum_frequency``, ``type``) are this project's reading where section 6 is
silent.

References
----------
.. [1] docs/references.md, section 6 (MPEG-I Haptics).
"""

from __future__ import annotations

import datetime as _dt
import math
from typing import Any

from .timeline import CONTROL_STEP_S, SHARPNESS_LOW_HZ, DriveTimeline, control_points

__all__ = ["hjif_document", "HJIF_TIMESCALE"]

#: Ticks per second (the format's default).
HJIF_TIMESCALE = 1000


def _ticks(t_s: float) -> int:
    return int(round(t_s * HJIF_TIMESCALE))


def _band_limits(freqs: list[float]) -> tuple[int, int]:
    if not freqs:
        return 0, 1
    return int(math.floor(min(freqs))), max(int(math.ceil(max(freqs))), int(math.floor(min(freqs))) + 1)


def _channel(tl: DriveTimeline, kind: str, c: int, step_s: float) -> dict[str, Any]:
    from .ahap import continuous_spans

    effects = []
    freqs: list[float] = []
    for k, (a, b) in enumerate(continuous_spans(tl, kind, c)):
        pts = control_points(tl, kind, c, step_s, start_s=a, end_s=b)
        pos = _ticks(a)
        effects.append({
            "id": k,
            "effect_type": "Basis",
            "position": pos,
            "phase": 0.0,
            "base_signal": "Sine",
            "keyframes": [
                {"relative_position": _ticks(p.t_s) - pos, "amplitude_modulation": round(p.amplitude, 4),
                 "frequency_modulation": round(p.frequency_hz, 3)}
                for p in pts
            ],
        })
        freqs += [p.frequency_hz for p in pts]
    taps = []
    tap_f: list[float] = []
    for p in tl.pulses(kind, c):
        f = p.drive.pulse_frequency_hz
        if f < SHARPNESS_LOW_HZ:
            taps.append({
                "id": len(taps),
                "effect_type": "Basis",
                "position": _ticks(p.t_s),
                "phase": 0.0,
                "base_signal": "Sine",
                "keyframes": [{"relative_position": 0, "amplitude_modulation": round(p.amplitude, 4),
                               "frequency_modulation": round(f, 3)}],
            })
            tap_f.append(f)
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
        "reference_device_id": 0,
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
    desc = f"tactilize: {kind} drive of a stroke of {tl.end_s:g} s"
    if tl.meta.get("image"):
        desc += f" on {tl.meta['image']}"
    return {
        "version": "2025",
        "profile": "Main",
        "level": 1,
        "date": _dt.date.today().isoformat(),
        "description": desc,
        "timescale": HJIF_TIMESCALE,
        "avatars": [{"id": 0, "lod": 0, "type": "Vibration"}],
        "perceptions": [
            {
                "id": 0,
                "avatar_id": 0,
                "description": "texture under the pen",
                "perception_modality": "Vibrotactile",
                "effect_library": [],
                "reference_devices": [
                    {"id": 0, "name": str(tl.meta.get("actuator", "tactile pen actuator")), "body_part_mask": 0,
                     "minimum_frequency": float(lo_hz), "maximum_frequency": float(hi_hz), "type": "Unknown"}
                ],
                "channels": [_channel(tl, kind, c, step_s) for c in range(tl.channels)],
            }
        ],
        "syncs": [],
    }
