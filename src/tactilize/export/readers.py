"""Readers for the files written here: AHAP, ``.hjif`` and ``.haptic`` back to drive over time.

Each returns a :class:`HapticTrack`: the continuous part as points of
(time [s], amplitude 0..1, frequency [Hz]) and the taps as (time [s],
amplitude, frequency [Hz]).  They read what this package writes (and files
laid out the same way); they are not general players.  Semantics as
docs/references.md, section 6 gives them: AHAP's dynamic intensity multiplies
an event's intensity and its dynamic sharpness is added, clamped to 0..1; a
curve holds its last value until the next curve.

References
----------
.. [1] docs/references.md, section 6 (AHAP parameter curves).
"""

from __future__ import annotations

import bisect
import json
from dataclasses import dataclass, field
from typing import Any

from ..errors import SignalError
from .timeline import ControlPoint, frequency_from_sharpness

__all__ = ["HapticTrack", "read_ahap", "read_hjif", "read_haptic"]


@dataclass
class HapticTrack:
    """Drive over time read back from a file.

    Attributes
    ----------
    points : list of ControlPoint
        The continuous part: time [s], amplitude 0..1, frequency [Hz].
    taps : list of ControlPoint
        One per transient: time [s], amplitude, frequency [Hz] (for AHAP the
        train's frequency from the interval to the next tap; 0 for the last).
    channels : int
    """

    points: list[ControlPoint] = field(default_factory=list)
    taps: list[ControlPoint] = field(default_factory=list)
    channels: int = 1


def _load(data: Any, what: str) -> Any:
    if isinstance(data, (bytes, bytearray, str)):
        try:
            return json.loads(data)
        except ValueError as exc:
            raise SignalError(f"<{what}>", f"not valid JSON ({exc})") from None
    return data


def _taps_from_times(taps: list[tuple[float, float]]) -> list[ControlPoint]:
    out = []
    for i, (t, a) in enumerate(taps):
        f = 1.0 / (taps[i + 1][0] - t) if i + 1 < len(taps) and taps[i + 1][0] > t else 0.0
        out.append(ControlPoint(t, a, f))
    return out


class _Curves:
    """The dynamic parameter of one ID: curves in time order, each (start, [(t_abs, v)])."""

    def __init__(self, curves: list[tuple[float, list[tuple[float, float]]]], neutral: float) -> None:
        self.curves = sorted(curves, key=lambda c: c[0])
        self.starts = [c[0] for c in self.curves]
        self.neutral = neutral

    def value(self, t: float) -> float:
        """The value at ``t`` [s] from the latest curve starting at or before ``t``."""
        i = bisect.bisect_right(self.starts, t + 1e-9) - 1
        if i < 0:
            return self.neutral
        pts = self.curves[i][1]
        if t <= pts[0][0]:
            return pts[0][1]
        for (t0, v0), (t1, v1) in zip(pts, pts[1:]):
            if t0 <= t <= t1:
                return v0 if t1 == t0 else v0 + (t - t0) / (t1 - t0) * (v1 - v0)
        return pts[-1][1]


def read_ahap(data: Any) -> HapticTrack:
    """An AHAP document (dict, bytes or text) as a :class:`HapticTrack`."""
    doc = _load(data, "ahap")
    if not isinstance(doc, dict) or not isinstance(doc.get("Pattern"), list):
        raise SignalError("<ahap>", "not an AHAP document (no Pattern list)")
    events: list[dict[str, Any]] = []
    curves: dict[str, list[tuple[float, list[tuple[float, float]]]]] = {
        "HapticIntensityControl": [], "HapticSharpnessControl": []}
    for entry in doc["Pattern"]:
        if "Event" in entry:
            events.append(entry["Event"])
        elif "ParameterCurve" in entry:
            c = entry["ParameterCurve"]
            t0 = float(c["Time"])
            pts = [(t0 + float(p["Time"]), float(p["ParameterValue"])) for p in c["ParameterCurveControlPoints"]]
            curves.setdefault(c["ParameterID"], []).append((t0, pts))
    ic = _Curves(curves["HapticIntensityControl"], 1.0)
    sc = _Curves(curves["HapticSharpnessControl"], 0.0)
    track = HapticTrack()
    taps = []
    for ev in sorted(events, key=lambda e: float(e["Time"])):
        params = {p["ParameterID"]: float(p["ParameterValue"]) for p in ev.get("EventParameters", [])}
        inten, sharp = params.get("HapticIntensity", 1.0), params.get("HapticSharpness", 0.5)
        t0 = float(ev["Time"])
        if ev["EventType"] == "HapticTransient":
            taps.append((t0, inten * ic.value(t0)))
            continue
        t1 = t0 + float(ev.get("EventDuration", 0.0))
        times = sorted({t0, t1} | {t for _, pts in ic.curves + sc.curves for t, _ in pts if t0 <= t <= t1})
        for t in times:
            # A curve that starts where the event ends belongs to what comes after.
            a = inten * _in_event(ic, t, t0, t1)
            s = min(1.0, max(0.0, sharp + _in_event(sc, t, t0, t1)))
            track.points.append(ControlPoint(t, a, frequency_from_sharpness(s)))
    track.taps = _taps_from_times(taps)
    return track


def _in_event(c: _Curves, t: float, t0: float, t1: float) -> float:
    """The curve value at ``t`` among curves that start inside [t0, t1)."""
    i = bisect.bisect_right(c.starts, t + 1e-9) - 1
    while i >= 0 and c.starts[i] >= t1 - 1e-9 and c.starts[i] > t0 + 1e-9:
        i -= 1
    if i < 0:
        return c.neutral
    sub = _Curves([c.curves[i]], c.neutral)
    return sub.value(t)


def read_hjif(data: Any, channel: int = 0) -> HapticTrack:
    """An ``.hjif`` document as a :class:`HapticTrack` (one channel of the first perception)."""
    doc = _load(data, "hjif")
    try:
        scale = float(doc.get("timescale", 1000))
        perception = doc["perceptions"][0]
        chans = perception["channels"]
        ch = chans[channel]
    except (KeyError, IndexError, TypeError, AttributeError):
        raise SignalError("<hjif>", "not an MPEG-I Haptics document (no perceptions[0].channels)") from None
    track = HapticTrack(channels=len(chans))
    for band in ch.get("bands", []):
        for eff in band.get("effects", []):
            pos = float(eff["position"])
            for kf in eff.get("keyframes", []):
                cp = ControlPoint((pos + float(kf["relative_position"])) / scale, float(kf["amplitude_modulation"]),
                                  float(kf["frequency_modulation"]))
                (track.taps if band["band_type"] == "Transient" else track.points).append(cp)
    track.points.sort(key=lambda p: p.t_s)
    track.taps.sort(key=lambda p: p.t_s)
    return track


def read_haptic(data: Any) -> HapticTrack:
    """A Meta ``.haptic`` document as a :class:`HapticTrack` (frequency mapped back over 55..200 Hz)."""
    from .haptic import haptic_hz

    doc = _load(data, "haptic")
    try:
        env = doc["signals"]["continuous"]["envelopes"]
        amp, freq = env["amplitude"], env["frequency"]
    except (KeyError, TypeError):
        raise SignalError("<haptic>", "not a .haptic document (no signals.continuous.envelopes)") from None
    f_at = {round(float(f["time"]), 6): float(f["frequency"]) for f in freq}
    track = HapticTrack()
    for p in amp:
        t, a = float(p["time"]), float(p["amplitude"])
        if "emphasis" in p:
            track.taps.append(ControlPoint(t, float(p["emphasis"]["amplitude"]), haptic_hz(float(p["emphasis"]["frequency"]))))
        elif a > 0:
            track.points.append(ControlPoint(t, a, haptic_hz(f_at.get(round(t, 6), 0.0))))
    return track
