"""Android vibration of a stroke's events: a primitive per event, an envelope where they come too fast.

The one Android document (:func:`android_events_document`, for every rendering: the events of
:func:`~.events.timeline_events`, a stroke's bumps or a steady drive's pulses) (docs/references.md, section 6 (Android
compositions), (Android envelopes) and (phone transients)):

``compositions``
    For ``VibrationEffect.startComposition()`` (API 30): per stretch of separate
    bumps, ``start_ms`` and its ``primitives``, each ``PRIMITIVE_CLICK`` (intensity
    0.5 and above) or ``PRIMITIVE_TICK`` (the light one), ``scale`` the bump's
    intensity, ``delay_ms`` from the previous primitive's *start*
    (``DELAY_TYPE_RELATIVE_START_OFFSET``, API 36; whole ms between rounded times,
    so they never drift) and ``t_ms`` from the stroke's start.  Before API 36 the
    delay counts from the previous primitive's *end*: subtract that primitive's
    duration (``Vibrator.getPrimitiveDurations``, API 31) from ``delay_ms``.  A
    composition ends at a continuous stretch and at a pause of :data:`MAX_DELAY_MS`
    or more.
``waveform_envelopes``, ``basic_envelopes``
    One or more per run of bumps closer than 20 ms, each with its ``start_ms``:
    amplitude (intensity) and frequency (the bumps' rate) on the 20 ms grid,
    within the segment limits of API 36 (a segment shorter than 20 ms is
    stretched to 20 ms).
``effects``
    What to play when: ``{"start_ms", "kind": "composition" | "waveform_envelope", "index"}``
    in time order (one vibrator plays one effect at a time).
``timings_ms``, ``amplitudes``
    ``createWaveform`` (API 26): each bump :data:`TAP_MS` on at its intensity
    (level 1 .. 255), each run held at its intensity on the grid.

References
----------
.. [1] docs/references.md, section 6 (Android compositions).
.. [2] docs/references.md, section 6 (phone transients).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .android_envelopes import ANDROID_LIMITS, MAX_SEGMENT_MS, MIN_SEGMENT_MS, envelopes, run_lengths
from .events import PHONE_TRANSIENT_S, BumpEvent, EventPlan, event_intensity, plan_events, run_points, timeline_events
from .timeline import CONTROL_STEP_S, DriveTimeline

__all__ = ["android_events_document", "PRIMITIVES", "DELAY_TYPES", "MAX_DELAY_MS", "TAP_MS", "CLICK_INTENSITY"]

#: The primitives a composition here uses.
PRIMITIVES = ("PRIMITIVE_CLICK", "PRIMITIVE_TICK")
#: ``Composition`` delay types (API 36); before it every delay is a pause after the previous primitive.
DELAY_TYPES = ("DELAY_TYPE_PAUSE", "DELAY_TYPE_RELATIVE_START_OFFSET")
#: A pause this long or longer [ms] starts a new composition: the longest delay a
#: device accepts is its own and not public, so none waits longer than an envelope segment may last.
MAX_DELAY_MS = MAX_SEGMENT_MS
#: On-time of a bump in the createWaveform fallback [ms]: the short end of an LRA's click.
TAP_MS = 10
#: A bump at this intensity or more is a click, below it a tick.
CLICK_INTENSITY = 0.5


def _compositions(plan: EventPlan) -> list[dict[str, Any]]:
    """The transients in compositions, cut at every run and at long pauses."""
    cuts = sorted(r.start_s for r in plan.runs)
    out: list[dict[str, Any]] = []
    last: BumpEvent | None = None
    for ev in plan.transients:
        t_ms = int(round(ev.t_s * 1e3))
        run_between = last is not None and any(last.t_s < c < ev.t_s for c in cuts)
        if last is None or run_between or t_ms - out[-1]["primitives"][-1]["t_ms"] >= MAX_DELAY_MS:
            out.append({"start_ms": t_ms, "delay_type": "DELAY_TYPE_RELATIVE_START_OFFSET", "primitives": []})
        prims = out[-1]["primitives"]
        a = event_intensity(ev.strength)
        prims.append({"primitive": "PRIMITIVE_CLICK" if a >= CLICK_INTENSITY else "PRIMITIVE_TICK",
                      "scale": round(a, 4), "delay_ms": t_ms - prims[-1]["t_ms"] if prims else 0, "t_ms": t_ms})
        last = ev
    return out


def _at_least_a_segment(envs: list[dict[str, Any]]) -> None:
    for env in envs:
        for c in env["control_points"]:
            c["duration_ms"] = max(c["duration_ms"], MIN_SEGMENT_MS)


def _starts(envs: list[dict[str, Any]], start_ms: int) -> list[dict[str, Any]]:
    """Each envelope piece with the time it starts: the run's start, then where the piece before ended."""
    out = []
    t = start_ms
    for env in envs:
        out.append({"start_ms": t, **env})
        t += sum(c["duration_ms"] for c in env["control_points"])
    return out


def android_events_document(tl: DriveTimeline, kind: str = "profile", channel: int = 0,
                            step_s: float = CONTROL_STEP_S) -> dict[str, Any]:
    """The Android document of one channel's events (:func:`~.events.timeline_events`: a stroke's
    bumps or a steady drive's pulses; see the module docstring)."""
    events = timeline_events(tl, kind, channel)
    plan = plan_events(events, PHONE_TRANSIENT_S, tl.end_s)
    total_ms = max(int(round(tl.end_s * 1e3)), 1)
    level = np.zeros(total_ms, dtype=np.int32)
    flat_all: list[dict[str, Any]] = []
    waveform: list[dict[str, Any]] = []
    basic: list[dict[str, Any]] = []
    for run in plan.runs:
        start = int(round(run.start_s * 1e3))
        # The grid from the run's whole millisecond: its segments are whole steps, none shorter
        # than a segment may be and lengthened (which would move every later piece).
        pts = run_points(run, start_s=start * 1e-3, step_s=step_s)
        flat, wf, bs = envelopes(pts)
        _at_least_a_segment(wf)
        _at_least_a_segment(bs)
        flat_all += flat
        waveform += _starts(wf, start)
        basic += _starts(bs, start)
        for p, q in zip(pts, pts[1:] + [None]):
            a, b = int(round(p.t_s * 1e3)), int(round((q.t_s if q else run.end_s) * 1e3))
            level[a:max(b, a + 1)] = max(1, int(round(255 * p.amplitude))) if p.amplitude > 0 else 0
    comps = _compositions(plan)
    for ev in plan.transients:
        s = int(round(ev.t_s * 1e3))
        level[s : min(s + TAP_MS, total_ms)] = max(1, int(round(255 * event_intensity(ev.strength))))
    timings, amps = run_lengths(level)
    effects = sorted(
        [{"start_ms": c["start_ms"], "kind": "composition", "index": i} for i, c in enumerate(comps)]
        + [{"start_ms": w["start_ms"], "kind": "waveform_envelope", "index": i} for i, w in enumerate(waveform)],
        key=lambda e: (e["start_ms"], e["kind"]))
    return {
        "timings_ms": timings,
        "amplitudes": amps,
        "repeat": -1,
        "envelope": flat_all,
        "waveform_envelopes": waveform,
        "basic_envelopes": basic,
        "compositions": comps,
        "effects": effects,
        "transient_min_interval_ms": round(PHONE_TRANSIENT_S * 1e3, 3),
        "limits": ANDROID_LIMITS,
        "duration_ms": int(round(tl.end_s * 1e3)),
        "bumps": len(events),
        "drive": tl.drives(kind, channel)[0].to_dict(),
        "kotlin": _kotlin(comps),
    }


def _kotlin(comps: list[dict[str, Any]]) -> str:
    lines = ["// one effect per entry of `effects`, started at its start_ms (a vibrator plays one at a time)"]
    if comps:
        lines.append("val first = VibrationEffect.startComposition()")
        for p in comps[0]["primitives"][:3]:
            lines.append(f"    .addPrimitive(VibrationEffect.Composition.{p['primitive']}, {p['scale']}f, {p['delay_ms']},"
                         " VibrationEffect.Composition.DELAY_TYPE_RELATIVE_START_OFFSET)")
        if len(comps[0]["primitives"]) > 3:
            lines.append("    // ... the rest of this composition's primitives")
        lines.append("    .compose()")
    lines.append("// a waveform_envelopes entry: VibrationEffect.WaveformEnvelopeBuilder(), as in the steady export")
    return "\n".join(lines)
