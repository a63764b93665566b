"""Meta Haptics ``.haptic`` files (amplitude and frequency envelopes) following a stroke.

docs/references.md, section 6 (Meta Haptics): JSON with an amplitude envelope
and a frequency envelope, each a list of breakpoints; frequency 0..1 is mapped
onto the device's own range.  The layout written here::

    {"version": {"major": 1, "minor": 0, "patch": 0},
     "metadata": {"editor": "tactilize", "source": ..., "project": "", "tags": [], "description": ...},
     "signals": {"continuous": {"envelopes": {
         "amplitude": [{"time": s, "amplitude": 0..1, "emphasis": {"amplitude": 0..1, "frequency": 0..1}?}, ...],
         "frequency": [{"time": s, "frequency": 0..1}, ...]}}}}

Breakpoint times increase strictly (a run's last value stands 0.5 ms before its
end, where the amplitude steps to zero).  One document for every rendering: the
events of the stroke (:func:`~.events.timeline_events`: a stroke's bumps, or a
steady drive's pulses).  An event at least 20 ms from its neighbours is a short
amplitude bump with an *emphasis* (Meta's tap) at its start (its amplitude the
event's intensity, its frequency the event's own); closer events (a train from
50 Hz up, a run of close bumps) follow the envelopes on the control grid
(intensity, rate as frequency).  Frequency is mapped linearly from
:data:`HAPTIC_LOW_HZ` .. :data:`HAPTIC_HIGH_HZ` (the example range of section
6) and clipped; the metadata states the mapping so a reader can undo it.

References
----------
.. [1] docs/references.md, section 6 (Meta Haptics).
"""

from __future__ import annotations

from typing import Any

from .events import PHONE_TRANSIENT_S, event_intensity, plan_events, run_points, timeline_events
from .timeline import CONTROL_STEP_S, DriveTimeline

__all__ = ["haptic_document", "HAPTIC_LOW_HZ", "HAPTIC_HIGH_HZ", "haptic_frequency", "haptic_hz"]

HAPTIC_LOW_HZ = 55.0
HAPTIC_HIGH_HZ = 200.0
#: A tap's amplitude bump lasts this long [s] (a phone actuator's shortest click).
TAP_S = 0.005
#: A continuous run's last breakpoint stands this long before the run's end [s],
#: where the amplitude steps to zero (breakpoint times must increase).
END_S = 0.0005


def haptic_frequency(frequency_hz: float) -> float:
    """Normalised frequency 0..1 for ``frequency_hz`` [Hz] (linear over 55..200 Hz, clipped)."""
    return min(1.0, max(0.0, (frequency_hz - HAPTIC_LOW_HZ) / (HAPTIC_HIGH_HZ - HAPTIC_LOW_HZ)))


def haptic_hz(frequency: float) -> float:
    """The inverse of :func:`haptic_frequency` [Hz]."""
    return HAPTIC_LOW_HZ + min(1.0, max(0.0, frequency)) * (HAPTIC_HIGH_HZ - HAPTIC_LOW_HZ)


def haptic_document(tl: DriveTimeline, kind: str = "profile", channel: int = 0, step_s: float = CONTROL_STEP_S) -> dict[str, Any]:
    """The ``.haptic`` document of one channel of a timeline (see the module docstring)."""
    # (time, priority, amplitude breakpoint, frequency breakpoint); breakpoint
    # times must increase, so of two at one time the higher priority stays:
    # a tap over a point of the continuous run over the run's closing zero.
    entries: list[tuple[float, int, dict[str, Any], dict[str, Any]]] = []

    def add(t: float, a: float, f_hz: float, prio: int, emphasis: bool = False) -> None:
        t = round(t, 6)
        point: dict[str, Any] = {"time": t, "amplitude": round(a, 4)}
        if emphasis:
            point["emphasis"] = {"amplitude": round(a, 4), "frequency": round(haptic_frequency(f_hz), 5)}
        entries.append((t, prio, point, {"time": t, "frequency": round(haptic_frequency(f_hz), 5)}))

    def run(b: float, pts: list[Any]) -> None:
        for i, p in enumerate(pts):
            # the run's last value just before its end, then down to zero at the end
            t = p.t_s if i < len(pts) - 1 or len(pts) == 1 else max(p.t_s - END_S, pts[i - 1].t_s + END_S)
            add(t, p.amplitude, p.frequency_hz, 1)
        add(b, 0.0, pts[-1].frequency_hz, 0)

    # An emphasis per event a phone plays apart, envelopes where they come faster (one rule for
    # a stroke's bumps and a steady drive's pulses: .events.timeline_events).
    plan = plan_events(timeline_events(tl, kind, channel), PHONE_TRANSIENT_S, tl.end_s)
    for r in plan.runs:
        run(r.end_s, run_points(r, step_s=step_s))
    for ev in plan.transients:
        add(ev.t_s, event_intensity(ev.strength), ev.frequency_hz, 2, emphasis=True)
        add(ev.t_s + TAP_S, 0.0, ev.frequency_hz, 0)
    entries.sort(key=lambda e: (e[0], -e[1]))
    amp: list[dict[str, Any]] = []
    freq: list[dict[str, Any]] = []
    for t, _, a_pt, f_pt in entries:
        if amp and t <= amp[-1]["time"]:
            continue
        amp.append(a_pt)
        freq.append(f_pt)
    if not amp or amp[0]["time"] > 0:
        amp.insert(0, {"time": 0.0, "amplitude": 0.0})
        freq.insert(0, {"time": 0.0, "frequency": freq[0]["frequency"] if freq else 0.0})
    what = f"events of the {kind}, channel {channel}"
    desc = (f"tactilize: {what}, {tl.end_s:g} s; "
            f"frequency 0..1 = {HAPTIC_LOW_HZ:g}..{HAPTIC_HIGH_HZ:g} Hz")
    return {
        "version": {"major": 1, "minor": 0, "patch": 0},
        "metadata": {"editor": "tactilize", "source": str(tl.meta.get("image", "")), "project": "", "tags": ["texture"],
                     "description": desc},
        "signals": {"continuous": {"envelopes": {"amplitude": amp, "frequency": freq}}},
    }
