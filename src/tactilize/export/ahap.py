"""Apple Core Haptics patterns (AHAP) that follow a stroke.

Rules (docs/references.md, section 6 (AHAP document), (AHAP parameter curves)
and (AHAP sharpness and frequency)):

* Where the pulse frequency is 65 Hz or more, continuous events, none longer
  than 30 s.  Each event's ``HapticIntensity`` is the largest intensity it
  reaches and its ``HapticSharpness`` the sharpness at its start; the stroke's
  changes ride on parameter curves: ``HapticIntensityControl`` = intensity /
  event intensity (a dynamic intensity *multiplies*), ``HapticSharpnessControl``
  = sharpness - event sharpness (a dynamic sharpness, -1..1 with 0 neutral, is
  *added*).  A steady drive therefore has neutral curves (1.0 and 0.0).  No
  curve has more than 16 control points: longer ones are split, each piece
  starting where the last ended.  After a run of continuous events, neutral
  curves put the dynamic parameters back, so later taps play as written.
* Where it is below 65 Hz (a phone cannot vibrate there continuously), one
  transient per pulse, at the pulse's own time: the taps of a rough texture.
  Intensity is the pulse height; sharpness follows the pulse's bandwidth,
  1 / width.  A pulse closer than 20 ms to the next or the one before (a train
  from 50 to 65 Hz, an irregular train's close pairs: a phone's actuator does not
  play them apart) is part of a continuous event instead (:func:`~.events.steady_plan`).
* Intensity of a continuous event is the pulse train's fundamental relative to
  a 10 % duty train (:func:`~.timeline.intensity_from_drive`); sharpness maps
  the pulse frequency linearly onto 0..1 over 65..300 Hz.
* A stroke over a surface (``tl.events``, the ``surface`` rendering) plays its
  bumps instead (:mod:`.events`): one transient per bump at least 20 ms from its
  neighbours (a phone's actuator plays them apart), intensity from the bump's
  strength, sharpness from the bump's own frequency; closer bumps make one
  continuous event per run, intensity and sharpness curves following the bumps'
  intensity and rate.

References
----------
.. [1] docs/references.md, section 6 (AHAP document).
.. [2] docs/references.md, section 6 (AHAP parameter curves).
.. [3] docs/references.md, section 6 (AHAP sharpness and frequency).
"""

from __future__ import annotations

from functools import partial
from typing import Any, Callable

from ..drive import Drive
from .events import PHONE_TRANSIENT_S, event_intensity, plan_events, run_points, steady_plan
from .timeline import (
    CONTROL_STEP_S,
    ControlPoint,
    DriveTimeline,
    continuous_spans,
    control_points,
    sharpness_from_frequency,
)

__all__ = ["ahap_document", "ahap_pattern", "AHAP_MAX_EVENT_S", "AHAP_MAX_CURVE_POINTS", "continuous_spans"]

#: Core Haptics limits one continuous event to 30 s.
AHAP_MAX_EVENT_S = 30.0
#: Control points per parameter curve, at most (docs/references.md, section 6 (AHAP sharpness and frequency)).
AHAP_MAX_CURVE_POINTS = 16


def _r(x: float, nd: int = 6) -> float:
    return round(float(x), nd) + 0.0


def _curve(pid: str, t0: float, pts: list[tuple[float, float]]) -> dict[str, Any]:
    return {
        "ParameterCurve": {
            "ParameterID": pid,
            "Time": _r(t0),
            "ParameterCurveControlPoints": [{"Time": _r(t - t0), "ParameterValue": _r(v, 4)} for t, v in pts],
        }
    }


def _chunks(pts: list[tuple[float, float]]) -> list[list[tuple[float, float]]]:
    """Pieces of at most 16 points; each starts at the last point of the one before."""
    n = AHAP_MAX_CURVE_POINTS
    out, i = [], 0
    while True:
        out.append(pts[i : i + n])
        if i + n >= len(pts):
            return out
        i += n - 1


def _continuous(events: list[dict[str, Any]], curves: list[dict[str, Any]], a: float, b: float, end_s: float,
                points: Callable[[float, float], list[ControlPoint]]) -> None:
    """Continuous events over [a, b) [s] (30 s pieces) following ``points(start, end)``, then neutral curves."""
    t = a
    while t < b - 1e-9:
        e1 = min(t + AHAP_MAX_EVENT_S, b)
        pts = points(t, e1)
        intensity = max(p.amplitude for p in pts)
        sharp = sharpness_from_frequency(pts[0].frequency_hz)
        events.append(_event(t, "HapticContinuous", intensity, sharp, e1 - t))
        ipts = [(p.t_s, p.amplitude / intensity if intensity > 0 else 0.0) for p in pts]
        spts = [(p.t_s, sharpness_from_frequency(p.frequency_hz) - sharp) for p in pts]
        for pid, series in (("HapticIntensityControl", ipts), ("HapticSharpnessControl", spts)):
            curves.extend(_curve(pid, c[0][0], c) for c in _chunks(series))
        t = e1
    if b < end_s - 1e-9:
        curves.append(_curve("HapticIntensityControl", b, [(b, 1.0)]))
        curves.append(_curve("HapticSharpnessControl", b, [(b, 0.0)]))


def ahap_document(tl: DriveTimeline, kind: str = "profile", channel: int = 0, step_s: float = CONTROL_STEP_S) -> dict[str, Any]:
    """The AHAP document (a dict) of one channel of a timeline (see the module docstring)."""
    if tl.plays_events(kind):
        return _surface_document(tl, step_s)
    events: list[dict[str, Any]] = []
    curves: list[dict[str, Any]] = []
    spans, taps = steady_plan(tl, kind, channel, PHONE_TRANSIENT_S)
    for a, b in spans:
        _continuous(events, curves, a, b, tl.end_s,
                    lambda t0, t1: control_points(tl, kind, channel, step_s, start_s=t0, end_s=t1))
    for p in taps:
        tap_sharpness = sharpness_from_frequency(1.0 / max(p.width_s, 1e-6))
        events.append(_event(p.t_s, "HapticTransient", p.amplitude, tap_sharpness))
    events.sort(key=lambda e: e["Event"]["Time"])
    meta = tl.meta
    first = tl.drives(kind, channel)[0]
    if len(tl.t_s) == 1:
        desc = (f"pulse train {first.pulse_frequency_hz:g} Hz, width {first.pulse_width_s * 1e3:g} ms, "
                f"amplitude {first.amplitude:g}, {tl.end_s:g} s")
    else:
        desc = f"stroke of {tl.end_s:g} s, {len(tl.t_s)} frames, {kind} drive of channel {channel}"
        if meta.get("image"):
            desc += f", {meta['image']}"
    return {"Version": 1.0, "Metadata": {"Project": "tactilize", "Description": desc}, "Pattern": events + curves}


def _surface_document(tl: DriveTimeline, step_s: float) -> dict[str, Any]:
    """A stroke's bumps: a transient per bump a phone plays apart, continuous events where they come faster."""
    plan = plan_events(tl.events or (), PHONE_TRANSIENT_S, tl.end_s)
    events: list[dict[str, Any]] = []
    curves: list[dict[str, Any]] = []
    for run in plan.runs:
        _continuous(events, curves, run.start_s, run.end_s, tl.end_s,
                    partial(run_points, run, step_s=step_s))
    for ev in plan.transients:
        events.append(_event(ev.t_s, "HapticTransient", event_intensity(ev.strength),
                             sharpness_from_frequency(ev.frequency_hz)))
    events.sort(key=lambda e: e["Event"]["Time"])
    desc = (f"stroke of {tl.end_s:g} s over a surface: {len(plan.transients)} bumps as transients, "
            f"{len(plan.runs)} continuous stretches where bumps come closer than {PHONE_TRANSIENT_S * 1e3:g} ms")
    if tl.meta.get("image"):
        desc += f", {tl.meta['image']}"
    return {"Version": 1.0, "Metadata": {"Project": "tactilize", "Description": desc}, "Pattern": events + curves}


def _event(t: float, kind: str, intensity: float, sharpness: float, duration: float | None = None) -> dict[str, Any]:
    ev: dict[str, Any] = {"Time": _r(t), "EventType": kind}
    if duration is not None:
        ev["EventDuration"] = _r(duration)
    ev["EventParameters"] = [
        {"ParameterID": "HapticIntensity", "ParameterValue": _r(intensity, 4)},
        {"ParameterID": "HapticSharpness", "ParameterValue": _r(sharpness, 4)},
    ]
    return {"Event": ev}


def ahap_pattern(drive: Drive, duration_s: float = 2.0) -> dict[str, Any]:
    """The AHAP document of one steady drive held for ``duration_s`` [s]."""
    return ahap_document(DriveTimeline.steady(drive, duration_s))
