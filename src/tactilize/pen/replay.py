"""A stroke replayed through the real-time path in simulated time: what the wire would be told when.

:func:`replay_stroke` cuts a stroke's samples into batches of ``batch_s`` [s] as
the page sends them, lets each arrive ``transport_s`` [s] after its newest
sample, runs the pen tracker and :class:`~tactilize.surface.stroke.SurfaceStroke`
as the server does, and plays the events as an output that can play them does:
each batch replaces the events not yet fired.  It returns the pulses that fired,
on the stroke's clock, so they can be compared with the true crossings.
Deterministic: no wall clock.

Units: SI (s, m).
"""

from __future__ import annotations

from typing import Any, Sequence

from .samples import PenSample
from .tracker import StrokeTracker
from ..surface.events import PulseEvent
from ..surface.stroke import SurfaceStroke

__all__ = ["replay_stroke"]


def replay_stroke(
    surface: Any,
    samples: Sequence[PenSample],
    *,
    batch_s: float = 0.004,
    transport_s: float = 0.001,
    tracker: StrokeTracker | None = None,
) -> list[PulseEvent]:
    """The pulses an event-playing output fires for a stroke (stroke clock [s]).

    Parameters
    ----------
    surface : SurfaceModel or CompositeSurface
    samples : sequence of PenSample
        The stroke, times increasing.
    batch_s : float
        Samples are sent in batches this long [s].
    transport_s : float
        Each batch arrives this long after its newest sample [s]; a pulse due
        before its batch arrives fires at the arrival.
    """
    tracker = tracker or StrokeTracker()
    stroke = SurfaceStroke(surface)
    fired: list[PulseEvent] = []
    schedule: list[PulseEvent] = []
    batches: list[list[PenSample]] = []
    for smp in samples:
        if batches and smp.t_s < batches[-1][0].t_s + batch_s:
            batches[-1].append(smp)
        else:
            batches.append([smp])
    for batch in batches:
        arrival = batch[-1].t_s + transport_s
        # Everything scheduled before this batch arrives has fired (on the output's
        # clock, a stroke time t plays at t + transport).
        for ev in schedule:
            if ev.t_s + transport_s <= arrival:
                fired.append(ev._replace(t_s=ev.t_s + transport_s))
        state = tracker.extend(batch)
        if state is None:
            schedule = []
            continue
        schedule = stroke.update(batch, state.speed_m_s, state.direction_rad, state.pressure)
        schedule = [ev for ev in schedule if ev.t_s + transport_s > arrival] + [
            ev._replace(t_s=arrival - transport_s) for ev in schedule if ev.t_s + transport_s <= arrival
        ]
    for ev in schedule:
        fired.append(ev._replace(t_s=ev.t_s + transport_s))
    fired.sort(key=lambda e: e.t_s)
    return fired
