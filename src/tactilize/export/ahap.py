"""Apple Core Haptics patterns (AHAP) that follow a stroke.

Rules (docs/references.md, section 6 (AHAP document), (AHAP parameter curves)
and (AHAP sharpness and frequency)):

* One document for every rendering: the events of the stroke
  (:func:`~.events.timeline_events`: the bumps a stroke over a surface crossed, or the
  pulses of a steady drive's train).  An event at least 20 ms from its neighbours (a
  phone's actuator plays them apart) is a ``HapticTransient``: intensity from its
  strength (a steady pulse's: its drive's intensity), sharpness from its own frequency
  (a bump's 1 / (2 x its half-prominence time), a pulse's 1 / its width).
* Closer events (a steady train from 50 Hz up, a run of close bumps) make one
  continuous event per run (:func:`~.events.plan_events`), none longer than 30 s:
  ``HapticIntensity`` is the largest intensity it reaches and ``HapticSharpness`` the
  sharpness of the events' rate at its start (linear over 65..300 Hz); the changes ride
  on parameter curves: ``HapticIntensityControl`` = intensity / event intensity (a
  dynamic intensity *multiplies*), ``HapticSharpnessControl`` = sharpness - event
  sharpness (a dynamic sharpness, -1..1 with 0 neutral, is *added*).  A steady drive
  therefore has neutral curves (1.0 and 0.0).  No curve has more than 16 control points:
  longer ones are split, each piece starting where the last ended.  After a run of
  continuous events, neutral curves put the dynamic parameters back, so later taps play
  as written.

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
from .events import PHONE_TRANSIENT_S, event_intensity, plan_events, run_points, timeline_events
from .timeline import CONTROL_STEP_S, ControlPoint, DriveTimeline, continuous_spans, sharpness_from_frequency

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
    """The AHAP document (a dict) of one channel of a timeline: its events (:func:`~.events.timeline_events`),
    a transient per event a phone plays apart, continuous events where they come faster."""
    plan = plan_events(timeline_events(tl, kind, channel), PHONE_TRANSIENT_S, tl.end_s)
    events: list[dict[str, Any]] = []
    curves: list[dict[str, Any]] = []
    for run in plan.runs:
        _continuous(events, curves, run.start_s, run.end_s, tl.end_s,
                    partial(run_points, run, step_s=step_s))
    for ev in plan.transients:
        events.append(_event(ev.t_s, "HapticTransient", event_intensity(ev.strength),
                             sharpness_from_frequency(ev.frequency_hz)))
    events.sort(key=lambda e: e["Event"]["Time"])
    first = tl.drives(kind, channel)[0]
    if len(tl.t_s) == 1 and tl.events is None:
        desc = (f"pulse train {first.pulse_frequency_hz:g} Hz, width {first.pulse_width_s * 1e3:g} ms, "
                f"amplitude {first.amplitude:g}, {tl.end_s:g} s")
    else:
        desc = f"stroke of {tl.end_s:g} s, {len(tl.t_s)} frames, {kind} of channel {channel}"
    desc += (f": {len(plan.transients)} transients, {len(plan.runs)} continuous stretches where pulses come "
             f"closer than {PHONE_TRANSIENT_S * 1e3:g} ms")
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
