"""A stroke's bumps as the parametric exports play them: a transient per bump, or a continuous stretch.

A profile whose rendering is ``surface`` fires one pulse per bump the tip crosses
(docs/surfaces.md).  An export plays the events the stroke's rendering fired along the
one whole-stroke path (:func:`tactilize.surface.playback.play_stroke`, in
:func:`~.stroke.run_stroke`), the ones its wire column played (:func:`bump_events`).
Each event also carries the bump's own frequency, from how long the tip takes to cross
it, read on the profile along the stroke's path.

:func:`plan_events` splits the events for a format whose player has a shortest
interval between two transients it can play apart (``min_interval_s``): bumps
at least that far from their neighbours become one transient each; a run of
closer bumps becomes one continuous stretch whose intensity and rate follow the
bumps (:func:`run_points`).  The intervals come from the players:
:data:`PHONE_TRANSIENT_S` for a phone's actuator (AHAP, Android, ``.haptic``),
the MPEG reference synthesiser's transient for ``.hjif`` (:data:`HJIF_TRANSIENT_S`).

Rules, stated once (docs/surfaces.md, "Exports"):

* intensity of a bump of strength s > 0 is ``INTENSITY_FLOOR ** (1 - s)``: the
  strength is a place in a felt band spaced in decibels, as on the wire; the least
  felt bump plays 20 dB below full intensity.  A bump of strength 0 (pressure 0)
  plays nothing.
* a bump's frequency is ``1 / (2 d)`` with d the time the tip spends above half
  the bump's prominence: the fundamental of a raised cosine crossed in 2 d.  AHAP
  sharpness maps it over 65 .. 300 Hz, as every frequency here.
* a continuous stretch runs from its first bump to its last plus one mean interval
  (never into the next bump); its points sit on the phone formats' 20 ms control
  grid, the rate as frequency.

Units: SI (s, Hz); strength and intensity 0 .. 1.

References
----------
.. [1] docs/references.md, section 6 (phone transients).
.. [2] docs/references.md, section 6 (MPEG-I synthesiser).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, Sequence, TypeVar

import numpy as np

from .timeline import CONTROL_STEP_S, ControlPoint, _simplify

if TYPE_CHECKING:  # the surfaces load scipy: not at import
    from ..surface.model import SurfaceLike

__all__ = [
    "BumpEvent",
    "Run",
    "EventPlan",
    "bump_events",
    "plan_events",
    "run_points",
    "event_intensity",
    "PHONE_TRANSIENT_S",
    "HJIF_TRANSIENT_S",
    "timeline_events",
    "drive_strength",
    "INTENSITY_FLOOR",
]


#: Times this close [s] are the same instant (float rounding of whole microseconds).
TIME_TOLERANCE_S = 1e-9


class _HasTime(Protocol):
    @property
    def t_s(self) -> float: ...


_Timed = TypeVar("_Timed", bound=_HasTime)

#: Shortest interval [s] at which a phone's actuator plays two transients apart: an
#: LRA's click lasts 10 .. 20 ms (docs/references.md, section 6 (phone transients)).
PHONE_TRANSIENT_S = 0.020
#: The MPEG reference synthesiser plays every transient as two cycles in 22 ms
#: (docs/references.md, section 6 (MPEG-I synthesiser)).
HJIF_TRANSIENT_S = 0.022
#: Intensity of the least felt bump (strength 0+): 20 dB below full.
INTENSITY_FLOOR = 0.1


class BumpEvent(NamedTuple):
    """One bump crossed, as an export plays it.

    Attributes
    ----------
    t_s : float
        When the tip crosses it [s], from the export's start.
    strength : float
        The surface rendering's strength, 0 .. 1 (:class:`tactilize.surface.PulseEvent`).
    frequency_hz : float
        The bump's own frequency [Hz]: 1 / (2 x the time spent above half its prominence).
    clamped : tuple of str
        As the PulseEvent's (``cluster``, ``rate_only``, ``merged``).
    """

    t_s: float
    strength: float
    frequency_hz: float
    clamped: tuple[str, ...] = ()


class Run(NamedTuple):
    """Bumps too close for separate transients: one continuous stretch [start_s, end_s) [s]."""

    start_s: float
    end_s: float
    events: tuple[BumpEvent, ...]


class EventPlan(NamedTuple):
    """What a format plays: ``transients`` (one per bump) and ``runs`` (continuous stretches)."""

    transients: tuple[BumpEvent, ...]
    runs: tuple[Run, ...]
    min_interval_s: float


def event_intensity(strength: float) -> float:
    """Intensity 0 .. 1 of a bump of ``strength`` (0 for none; see the module docstring)."""
    s = min(1.0, max(0.0, float(strength)))
    return 0.0 if s <= 0.0 else INTENSITY_FLOOR ** (1.0 - s)


class StrokePath(Protocol):
    """What :func:`bump_events` reads of a stroke (a :class:`~.stroke.Stroke` is one): sample
    times [s] and positions [display m]."""

    @property
    def t_s(self) -> Sequence[float]: ...

    @property
    def x_m(self) -> Sequence[float]: ...

    @property
    def y_m(self) -> Sequence[float]: ...


def bump_events(events: Sequence[Any], stroke: StrokePath, surface: SurfaceLike | None, *, origin_s: float = 0.0,
                end_s: float = math.inf) -> tuple[BumpEvent, ...]:
    """The pulse ``events`` a stroke's surface rendering fired, timed from ``origin_s`` [s], those in
    [0, ``end_s``), each with its bump's own frequency read along the stroke's path.

    Parameters
    ----------
    events : sequence of PulseEvent
        What the rendering fired (:func:`tactilize.surface.playback.play_stroke`), stroke clock [s].
    stroke : Stroke
        Samples: times [s], positions [display m].
    surface : SurfaceModel, CompositeSurface or a mirrored one, or None
        What the stroke crossed (None: no frequency, 0).
    origin_s : float
        Stroke time [s] of the export's 0.
    end_s : float
        Length of the export [s].
    """
    kept = [e for e in events if 0.0 <= e.t_s - origin_s < end_s]
    freq = _bump_frequencies([e.t_s for e in kept], stroke, surface) if kept and surface is not None else [0.0] * len(kept)
    return tuple(BumpEvent(e.t_s - origin_s, e.strength, f, e.clamped) for e, f in zip(kept, freq))


def _bump_frequencies(times_s: Sequence[float], stroke: StrokePath, surface: SurfaceLike) -> list[float]:
    """Each event's bump frequency [Hz]: 1 / (2 x the time the tip spends above half the bump's
    prominence), read on the profile along the stroke's path at the crest nearest the event's time
    (an event handed late is a little after its crest)."""
    from scipy.signal import peak_widths

    from ..surface.bumps import resample_path

    if len(stroke.t_s) < 2:
        return [0.0] * len(times_s)
    t, x, y, _ = resample_path(stroke.t_s, stroke.x_m, stroke.y_m, surface.step_m)
    h = surface.regions(x, y)[0]
    if h.size < 3:
        return [0.0] * len(times_s)
    idx = np.clip(np.searchsorted(t, np.asarray(times_s, dtype=float)), 1, h.size - 2)
    crest = []
    for i in idx.tolist():
        # climb to the crest the event's time falls beside
        while 0 < i < h.size - 1 and max(h[i - 1], h[i + 1]) > h[i]:
            i = i - 1 if h[i - 1] > h[i + 1] else i + 1
        crest.append(min(max(i, 1), h.size - 2))
    _, _, left, right = peak_widths(h, np.array(crest), rel_height=0.5)
    grid = np.arange(h.size)
    half_s = np.interp(right, grid, t) - np.interp(left, grid, t)
    return [1.0 / (2.0 * d) if d > 0 else 0.0 for d in half_s.tolist()]


def close_groups(items: Sequence[_Timed], min_interval_s: float) -> list[list[_Timed]]:
    """``items`` (in time order, each with ``t_s`` [s]) in groups: one that comes less than
    ``min_interval_s`` [s] after the one before joins its group.  A group of one is a tap
    a player plays apart; a longer one plays as a continuous stretch."""
    groups: list[list[_Timed]] = []
    for e in items:
        # (within a nanosecond counts as the interval itself: a 50 Hz train's pulses, 20 ms
        # apart in whole microseconds, differ from 0.02 by float rounding either way)
        if groups and e.t_s - groups[-1][-1].t_s < min_interval_s - TIME_TOLERANCE_S:
            groups[-1].append(e)
        else:
            groups.append([e])
    return groups


def plan_events(events: Sequence[BumpEvent], min_interval_s: float, end_s: float = math.inf) -> EventPlan:
    """Split ``events`` into transients and continuous runs for a player's ``min_interval_s`` [s].

    Consecutive events closer than ``min_interval_s`` form a run; an event at
    least that far from both neighbours is a transient (none for strength 0).
    """
    groups = close_groups(sorted(events, key=lambda e: e.t_s), min_interval_s)
    transients: list[BumpEvent] = []
    runs: list[Run] = []
    for i, g in enumerate(groups):
        if len(g) == 1:
            if event_intensity(g[0].strength) > 0:
                transients.append(g[0])
            continue
        mean_iv = (g[-1].t_s - g[0].t_s) / (len(g) - 1)
        nxt = groups[i + 1][0].t_s if i + 1 < len(groups) else math.inf
        end = min(g[-1].t_s + mean_iv, nxt, end_s)
        if end > g[0].t_s:
            runs.append(Run(g[0].t_s, end, tuple(g)))
    return EventPlan(tuple(transients), tuple(runs), float(min_interval_s))


def drive_strength(drive: Any) -> float:
    """The strength 0 .. 1 a steady drive's pulse plays at: the one whose intensity
    (:func:`event_intensity`) is the drive's (:func:`~.timeline.intensity_from_drive`), so a
    steady train's events play as loud as its drive did; a drive quieter than the least felt
    bump plays as that one (strength 0+), an off drive not at all."""
    from .timeline import intensity_from_drive

    i = intensity_from_drive(drive)
    return 0.0 if i <= 0.0 else min(1.0, max(1e-6, 1.0 + math.log10(i)))


def timeline_events(tl: Any, kind: str = "profile", channel: int = 0) -> tuple[BumpEvent, ...]:
    """The one events timeline every parametric format plays for one channel of ``tl``.

    The events the stroke's rendering fired (``tl.events``: a stroke over a surface), else
    the pulses of the drive over time (``kind``: a steady rendering's, or what the wire
    applied) as the synthesiser schedules them (:meth:`~.timeline.DriveTimeline.pulses`:
    phase-continuous, an irregular drive jittered as on the wire; here at 1 ns, so a train's
    rate reads back exact): each pulse an event of :func:`drive_strength` at its train's
    frequency."""
    if kind == "profile" and tl.events is not None:
        return tuple(tl.events)
    return tuple(BumpEvent(p.t_s, drive_strength(p.drive), p.drive.pulse_frequency_hz, p.drive.clamped)
                 for p in tl.pulses(kind, channel, rate_hz=1_000_000_000))


def run_points(run: Run, start_s: float | None = None, end_s: float | None = None,
               step_s: float = CONTROL_STEP_S) -> list[ControlPoint]:
    """A run's intensity and rate [Hz] on the control grid over [start_s, end_s] (the whole run by default).

    Grid times are whole steps from ``start_s`` plus the end (a last interval
    shorter than a step merges into the one before); points a line already gives
    are dropped, as for the steady drive (:func:`~.timeline.control_points`).
    """
    from ..surface.events import local_rate_hz

    a = run.start_s if start_s is None else start_s
    b = run.end_s if end_s is None else end_s
    t = np.array([e.t_s for e in run.events])
    inten = np.array([event_intensity(e.strength) for e in run.events])
    rate = local_rate_hz(t)
    n = max(1, int(math.floor((b - a) / step_s + 1e-9)))
    times = [a + k * step_s for k in range(n)] + [b]
    if len(times) > 2 and times[-1] - times[-2] < step_s - 1e-9:
        del times[-2]
    pts = [ControlPoint(float(x), float(np.interp(x, t, inten)), float(np.interp(x, t, rate))) for x in times]
    return _simplify(pts, 0.005, 0.01, 1.0)
