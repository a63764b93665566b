"""The events a stroke's rendering fired, as the parametric exports play them: a transient each, or a
continuous stretch.

An export plays the events the stroke's rendering fired along the one whole-stroke path
(:func:`tactilize.surface.playback.play_stroke`, in :func:`~.stroke.run_stroke`), the ones its
wire column played (:func:`fired_events`), whatever the rendering: a steady rendering fires its
drive's regular train (each pulse carries the strength and frequency of the drive that handed it),
the ``surface`` rendering one pulse per bump the tip crosses (docs/surfaces.md; each carries its
bump's own frequency, from how long the tip takes to cross it, read on the profile along the
stroke's path).  Rows of drives without a stroke (a drive held; what the wire applied) play the
steady rendering's train of each row's drive (:func:`timeline_events`).

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
    "fired_events",
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
    """What :func:`fired_events` reads of a stroke (a :class:`~.stroke.Stroke` is one): sample
    times [s] and positions [display m]."""

    @property
    def t_s(self) -> Sequence[float]: ...

    @property
    def x_m(self) -> Sequence[float]: ...

    @property
    def y_m(self) -> Sequence[float]: ...


def fired_events(played: Any, stroke: StrokePath, surface: SurfaceLike | None, *, origin_s: float = 0.0,
                 end_s: float = math.inf) -> tuple[BumpEvent, ...]:
    """The events a stroke's rendering fired, timed from ``origin_s`` [s], those in [0, ``end_s``).

    An event a regular frame handed (a steady rendering's train) plays as its drive did: the
    strength :func:`drive_strength`, the drive's pulse frequency.  Any other event is a bump
    crossed: its own strength, and its bump's frequency read along the stroke's path.

    Parameters
    ----------
    played : PlayedStroke
        What the rendering fired (:func:`tactilize.surface.playback.play_stroke`): its events
        on the stroke's clock [s], and for each the drive of the frame that handed it and
        whether that frame was its drive's regular train.
    stroke : Stroke
        Samples: times [s], positions [display m].
    surface : SurfaceModel, CompositeSurface or a mirrored one, or None
        What the stroke crossed (None: a bump's frequency is 0).
    origin_s : float
        Stroke time [s] of the export's 0.
    end_s : float
        Length of the export [s].
    """
    kept = [(e, d, r) for e, (d, r) in zip(played.events, played.regular) if 0.0 <= e.t_s - origin_s < end_s]
    bumps = [e.t_s for e, _, r in kept if not r]
    freq = iter(_bump_frequencies(bumps, stroke, surface) if bumps and surface is not None else [0.0] * len(bumps))
    return tuple(BumpEvent(e.t_s - origin_s, drive_strength(d), d.pulse_frequency_hz, e.clamped) if r
                 else BumpEvent(e.t_s - origin_s, e.strength, next(freq), e.clamped) for e, d, r in kept)


def _bump_frequencies(times_s: Sequence[float], stroke: StrokePath, surface: SurfaceLike) -> list[float]:
    """Each event's bump frequency [Hz]: 1 / (2 x the time the tip spends above half the bump's
    prominence), read on the profile along the stroke's path at the crest nearest the event's time
    (an event handed late is a little after its crest).

    A bump whose crest the path does not cross (the pen stopped on its flank after the prediction
    had fired it) has no such time: it takes the frequency of the nearest event that has one (0 when
    none has), so a format does not play it as the lowest sharpness there is."""
    import warnings

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
    with warnings.catch_warnings():  # (a crest not crossed has no prominence nor width: handled below)
        warnings.filterwarnings("ignore", message="some peaks have a (width|prominence) of 0")
        _, _, left, right = peak_widths(h, np.array(crest), rel_height=0.5)
    grid = np.arange(h.size)
    half_s = np.interp(right, grid, t) - np.interp(left, grid, t)
    freq = np.array([1.0 / (2.0 * d) if d > 0 else 0.0 for d in half_s.tolist()])
    read = np.flatnonzero(freq > 0)
    if read.size and read.size < freq.size:
        ts = np.asarray(times_s, dtype=float)
        for k in np.flatnonzero(freq <= 0).tolist():
            freq[k] = freq[read[np.argmin(np.abs(ts[read] - ts[k]))]]
    return freq.tolist()


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

    The events the stroke's rendering fired (``tl.events``, :func:`fired_events`), for the
    profile's drive.  Rows without them (a drive held, no stroke; ``kind="wire"``, what the wire
    applied) play a steady rendering's train of each row's drive from the row's start
    (:class:`~tactilize.surface.rendering.SteadyTrain`), each pulse an event of
    :func:`drive_strength` at the train's frequency."""
    if kind == "profile" and tl.events is not None:
        return tuple(tl.events)
    from ..surface.rendering import SteadyTrain

    out: list[BumpEvent] = []
    train = SteadyTrain()
    bounds = list(tl.t_s[1:]) + [tl.end_s]
    for t0, t1, d in zip(tl.t_s, bounds, tl.drives(kind, channel)):
        train.set_drive(d, t0)
        pulses = train.pulses(t0, t1 - t0)
        train.played(pulses, t1)
        s = drive_strength(d)
        out.extend(BumpEvent(e.t_s, s, d.pulse_frequency_hz, e.clamped) for _, e in pulses)
    return tuple(out)


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
