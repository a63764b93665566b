"""The rendering interface: what every rendering implements and every consumer calls.

A :class:`Rendering` is made once per picture and profile (:func:`rendering_for`, the one place
that reads a profile's ``rendering``).  Per pen batch, :meth:`Rendering.frame` takes the tracked
pen and returns a :class:`Frame`: the pulse events from the newest sample on and the operating
point (a :class:`~tactilize.drive.Drive`) they imply.  A steady rendering's frame is a regular
train (one event per period of its Drive, ``regular`` True: an output that synthesises trains may
play the Drive, which describes them exactly); the surface rendering's are the bumps the tip
crosses (docs/surfaces.md).  :meth:`Rendering.straight` is what the rendering gives a picture
stroked steadily in a straight line (the report's rows), :meth:`Rendering.steady_drive` its Drive (the
commands and the catalogue's rows), :meth:`Rendering.sample_drives` the drive it rendered at each sample
of a batch (a stroke log), and :attr:`Rendering.reads_surface` whether a material or a relief changes
what it renders.

Switching renderings changes the frames, not the code that plays them: the pen's renderer, the
exports, the reports, the experiments' stroke log and the catalogue call these methods alone; none of
them reads the profile's ``rendering`` (:func:`rendering_kind` and :func:`rendering_for` do).

Units: SI (s, m, Hz).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, Protocol, Sequence

import numpy as np

from ..drive import Drive, interval_cv, jitter_offset, jitter_periods
from .events import EventStatistics, PulseEvent, event_statistics
from .model import SurfaceLike
from .straight import STROKE_S, MirroredSurface, straight_stroke

__all__ = ["Frame", "Straight", "Rendering", "SteadyRendering", "SurfaceRendering", "rendering_for",
           "rendering_kind", "rendered_drive", "train_events", "SteadyTrain", "HORIZON_S", "surface_stroke_drive",
           "stroke_events"]

#: How far ahead a frame's events reach [s]: the surface stroke's prediction horizon.
HORIZON_S = 0.025


class Frame(NamedTuple):
    """One pen batch rendered.

    Attributes
    ----------
    events : tuple of PulseEvent
        Pulses from the newest sample on [s, the stroke's clock], those not yet fired.
    drive : Drive
        The operating point they imply (one per rendering; the pen's renderer splits it per channel).
    regular : bool
        The events are the drive's own regular train, so the drive describes them exactly.
    """

    events: tuple[PulseEvent, ...]
    drive: Drive
    regular: bool


class Straight(NamedTuple):
    """What a rendering gives a picture stroked steadily in a straight line
    (:func:`~.straight.straight_stroke`, :data:`~.straight.STROKE_S` long).

    Attributes
    ----------
    drive : Drive
        The stroke's operating point: the steady rendering's law, the surface rendering's
        equivalent Drive of the stroke's events.
    events : tuple of PulseEvent
        The pulses over the stroke [s from its start].
    rate_hz : float
        Pulses per second [1/s] (0 when none).
    interval_cv : float
        Coefficient of variation of the intervals between them.
    strength : float or None
        Mean strength in the felt band [0, 1] (a steady drive's own, None where its width law
        places none).
    pulses : int
        How many pulses the stroke has.
    clamped : tuple of str
        The limits that clamped the pulses (a steady rendering's: its drive's).
    """

    drive: Drive
    events: tuple[PulseEvent, ...]
    rate_hz: float
    interval_cv: float
    strength: float | None
    pulses: int
    clamped: tuple[str, ...]


#: Per sample of a batch, what the stroke's tracker had: (speed [m/s], direction [rad] or None,
#: pressure or None).
SampleState = tuple[float, "float | None", "float | None"]


class TrackedPen(Protocol):
    """What a rendering reads of the tracked pen (:class:`tactilize.pen.tracker.StrokeState` is one)."""

    @property
    def t_s(self) -> float: ...

    @property
    def speed_m_s(self) -> float: ...

    @property
    def direction_rad(self) -> float | None: ...

    @property
    def pressure(self) -> float | None: ...

    @property
    def speed_now_m_s(self) -> float: ...

    @property
    def direction_now_rad(self) -> float | None: ...


class Rendering(Protocol):
    """A rendering: made once per picture and profile, fed pen batches (see the module docstring)."""

    @property
    def name(self) -> str:
        """``"steady"`` or ``"surface"``."""
        ...

    @property
    def newly_fired(self) -> int:
        """Pulses that became due with the latest frame."""
        ...

    @property
    def surface(self) -> SurfaceLike | None:
        """The picture as a surface, or None."""
        ...

    @property
    def reads_surface(self) -> bool:
        """The rendering renders the picture's surface: a material or a relief changes what it renders."""
        ...

    profile: Any

    def frame(self, state: TrackedPen, features: Any, batch: Sequence[Any],
              played_until_s: float | None = None) -> Frame:
        """The batch ``batch`` (pen samples, SI) with the tracker's estimate ``state`` and the
        ``features`` under the pen; ``played_until_s`` [s], the stroke time the output has reached."""
        ...

    def reset(self) -> None:
        """Forget the stroke (a lift, a new picture)."""
        ...

    def straight(self, features: Any, speed_m_s: float, direction_rad: float | None = None,
                 pressure: float | None = None) -> Straight:
        """The picture (``features`` under the pen) stroked steadily in a straight line at ``speed_m_s``
        [m/s] in ``direction_rad`` [rad] (None: the laws' full speed, the stroke along +x) at ``pressure``."""
        ...

    def steady_drive(self, features: Any, speed_m_s: float, direction_rad: float | None = None) -> Drive:
        """The drive of the picture stroked steadily at ``speed_m_s`` [m/s]: :meth:`straight`'s."""
        ...

    def sample_drives(self, features: Any, states: Sequence[SampleState], frame_drive: Drive | None) -> list[Drive]:
        """The drive rendered at each sample of a batch (a stroke log's), given the tracker's
        ``states`` after each sample and the batch's frame drive (None: the batch made no frame)."""
        ...


def _train(drive: Drive, anchor_s: float, from_s: float, span_s: float, seed: int,
           first_index: int) -> list[tuple[int, PulseEvent]]:
    """:func:`train_events` with each pulse's index in the jitter pattern (``first_index + k``)."""
    if drive.is_off or drive.pulse_frequency_hz <= 0:
        return []
    period = 1.0 / drive.pulse_frequency_hz
    # At 1 MHz (the wire's schedule) the one-sample margin of jitter_periods is negligible.
    j = jitter_periods(drive, period * 1e6, max(1, round(drive.pulse_width_s * 1e6)))
    k = max(0, math.ceil((from_s - anchor_s) / period - 1e-9 - (0.5 * j if j else 0.0)))
    strength = 1.0 if drive.strength is None else float(drive.strength)
    out = []
    end = from_s + span_s
    while True:
        u = jitter_offset(first_index + k, seed) if j else 0.0
        if k == 0:
            u = 0.0 if first_index == 0 else max(u, 0.0)  # pulse 0 is never moved earlier
        t = anchor_s + (k + j * u) * period
        if t >= end and (not j or anchor_s + (k - 0.5 * j) * period >= end):
            break
        if from_s - 1e-9 * period <= t < end:
            out.append((first_index + k, PulseEvent(t, strength, drive.clamped)))
        k += 1
    return out


def train_events(drive: Drive, anchor_s: float, from_s: float, span_s: float = HORIZON_S,
                 seed: int = 0, first_index: int = 0) -> tuple[PulseEvent, ...]:
    """The train of ``drive`` in [``from_s``, ``from_s + span_s``) [s]: pulse ``k`` at
    ``anchor_s + (k + j u_k) / f`` [s] (the phase stays where the train started), jittered as
    the synthesiser jitters an irregular drive (``j`` of :func:`~tactilize.drive.jitter_periods`,
    ``u_k`` the seeded table from index ``first_index``).  Pulse 0 of a train that starts after
    silence (``first_index`` 0) is not moved; that of a train taking over from another drive is
    only delayed."""
    return tuple(e for _, e in _train(drive, anchor_s, from_s, span_s, seed, first_index))


class SteadyTrain:
    """A steady rendering's pulse train as its drive changes, by the synthesiser's rule
    (:class:`tactilize.synthesis.trains.PulseScheduler`): after silence the first pulse comes at
    once; a new drive's first pulse comes one of its periods after the last pulse played (not
    before the change), the jitter pattern running on; a pulse is played once.

    Parameters
    ----------
    seed : int
        Seed of the jitter of irregular drives.
    """

    def __init__(self, seed: int = 0) -> None:
        self.seed = int(seed)
        self.reset()

    def reset(self) -> None:
        """Silence: the next drive starts a train."""
        self._drive: Drive | None = None
        self._anchor_s = 0.0
        self._first = 0
        self._last: tuple[float, int] | None = None  # the last pulse played: time [s], index

    def set_drive(self, drive: Drive, now_s: float) -> None:
        """The train plays ``drive`` from ``now_s`` [s] on (an off drive is silence)."""
        if drive.is_off or drive.pulse_frequency_hz <= 0:
            self.reset()
            return
        if self._drive is None:
            self._anchor_s, self._first = now_s, 0
        elif drive != self._drive and self._last is not None:
            t, k = self._last
            self._anchor_s, self._first = max(now_s, t + 1.0 / drive.pulse_frequency_hz), k + 1
        self._drive = drive

    def pulses(self, from_s: float, span_s: float) -> list[tuple[int, PulseEvent]]:
        """(index, pulse) of the train in [``from_s``, ``from_s + span_s``) [s] not yet played."""
        if self._drive is None:
            return []
        after = -math.inf if self._last is None else self._last[0]
        return [(k, e) for k, e in _train(self._drive, self._anchor_s, from_s, span_s, self.seed, self._first)
                if e.t_s > after]

    def played(self, pulses: Sequence[tuple[int, PulseEvent]], until_s: float) -> None:
        """Of ``pulses`` (:meth:`pulses`), those due by ``until_s`` [s] have played."""
        for k, e in pulses:
            if e.t_s <= until_s and (self._last is None or e.t_s > self._last[0]):
                self._last = (e.t_s, k)


class SteadyRendering:
    """The profile's laws: one Drive from the features under the pen and the stroke's speed."""

    name = "steady"
    newly_fired = 0
    reads_surface = False

    def __init__(self, profile: Any, surface: SurfaceLike | None = None) -> None:
        self.profile = profile
        #: The picture's surface, kept for a later profile that renders it (:func:`rendering_for`).
        self.surface = surface
        self._train = SteadyTrain()
        self._handed: list[tuple[int, PulseEvent]] = []  # the latest frame's pulses

    def reset(self) -> None:
        self._train.reset()
        self._handed = []

    def frame(self, state: TrackedPen, features: Any, batch: Sequence[Any],
              played_until_s: float | None = None) -> Frame:
        drive = self.profile.drive(features, state.speed_m_s, state.direction_rad, state.pressure)
        played = state.t_s if played_until_s is None else max(state.t_s, played_until_s)
        # The pulses handed before and due by now have played; the drive changes from now on.
        self._train.played(self._handed, played)
        self._train.set_drive(drive, played)
        self._handed = self._train.pulses(state.t_s, HORIZON_S)
        return Frame(tuple(e for _, e in self._handed), drive, True)

    def straight(self, features: Any, speed_m_s: float, direction_rad: float | None = None,
                 pressure: float | None = None) -> Straight:
        """The law's Drive at that speed and its regular train over the stroke: rate, interval CV and
        strength are the drive's own (:func:`~tactilize.drive.interval_cv`)."""
        drive = self.profile.drive(features, speed_m_s, direction_rad, pressure)
        events = train_events(drive, 0.0, 0.0, STROKE_S)
        rate = 0.0 if drive.is_off else drive.pulse_frequency_hz
        return Straight(drive, events, rate, interval_cv(drive), drive.strength, len(events), drive.clamped)

    def steady_drive(self, features: Any, speed_m_s: float, direction_rad: float | None = None) -> Drive:
        """:meth:`straight`'s Drive, the law's, without the train it would lay out."""
        return self.profile.drive(features, speed_m_s, direction_rad)

    def sample_drives(self, features: Any, states: Sequence[SampleState], frame_drive: Drive | None) -> list[Drive]:
        """The law at each sample's state: a steady frame's drive is the law at the batch's last state,
        so the last sample takes ``frame_drive`` when there is one."""
        n = len(states)
        return [frame_drive if k == n - 1 and frame_drive is not None
                else self.profile.drive(features, speed_m_s=v, direction_rad=d, pressure=p)
                for k, (v, d, p) in enumerate(states)]


#: The window's Drive is made again when its rate moves by more than this share (the 0.5 %
#: resend rule of steady drives), ...
SAME_RATE_REL = 0.005
#: ...or the intervals' coefficient of variation by more than this (its regularity by 0.02), ...
SAME_CV = 0.005
#: ...or the mean strength by more than this (a hundredth of the felt band).
SAME_STRENGTH = 0.01


class SurfaceRendering:
    """A pulse per bump the stylus tip crosses, predicted ahead (:class:`~.stroke.SurfaceStroke`);
    the operating point is the equivalent Drive of the last :data:`~.equivalent.WINDOW_S`."""

    name = "surface"
    reads_surface = True

    def __init__(self, profile: Any, surface: SurfaceLike) -> None:
        from .stroke import SurfaceStroke

        self.profile = profile
        self.surface = surface
        self.stroke = SurfaceStroke(surface)
        self._stats: Any = None
        self._drive_of: Any = None  # the profile self._drive was made with
        self._drive = Drive.off()

    @property
    def newly_fired(self) -> int:
        return self.stroke.newly_fired

    def reset(self) -> None:
        self.stroke.reset()

    def frame(self, state: TrackedPen, features: Any, batch: Sequence[Any],
              played_until_s: float | None = None) -> Frame:
        from .equivalent import WINDOW_S, drive_of_statistics

        stroke = self.stroke
        if state.direction_rad is None or state.speed_m_s <= 0:
            # A resting pen adds no path and fires nothing (what was pending is withdrawn).
            stroke.update(batch, 0.0, None, state.pressure, played_until_s)
            stroke.rest()
            return Frame((), Drive.off(), False)
        # The path ahead is predicted with the velocity at the newest sample (the tracker's).
        events = stroke.update(batch, state.speed_now_m_s, state.direction_now_rad, state.pressure, played_until_s)
        # Most batches bring the same window, its predicted times moved by microseconds: the
        # same Drive object is kept then (a Drive and its limits cost more than comparing five
        # numbers, and the output keeps its plan of it).
        stats = stroke.window_statistics(WINDOW_S)
        if self._stats is None or self._drive_of is not self.profile or not _same_statistics(stats, self._stats):
            self._drive = drive_of_statistics(stats, self.profile)
            self._stats, self._drive_of = stats, self.profile
        return Frame(tuple(events), self._drive, False)

    def straight(self, features: Any, speed_m_s: float, direction_rad: float | None = None,
                 pressure: float | None = None) -> Straight:
        """The events of the straight stroke over the surface (:func:`surface_stroke_drive`),
        measured over the whole stroke, and their equivalent Drive; ``features`` are not read."""
        drive, events, stats = surface_stroke_drive(self.surface, self.profile, speed_m_s, direction_rad, pressure)
        return Straight(drive, tuple(events), stats.rate_hz, stats.interval_cv, stats.strength, stats.pulses,
                        stats.clamped)

    def steady_drive(self, features: Any, speed_m_s: float, direction_rad: float | None = None) -> Drive:
        """:meth:`straight`'s Drive."""
        return self.straight(features, speed_m_s, direction_rad).drive

    def sample_drives(self, features: Any, states: Sequence[SampleState], frame_drive: Drive | None) -> list[Drive]:
        """The frame's drive at every sample: the operating point is the window's, one per batch
        (off for a batch that made no frame: nothing was rendered)."""
        return [frame_drive or Drive.off()] * len(states)


def _same_statistics(a: Any, b: Any) -> bool:
    """Two windows' statistics make the same Drive: the same count and names, rate within
    :data:`SAME_RATE_REL`, CV within :data:`SAME_CV`, mean strength within :data:`SAME_STRENGTH`."""
    return (a.pulses == b.pulses and a.clamped == b.clamped and abs(a.rate_hz - b.rate_hz) <= SAME_RATE_REL * b.rate_hz
            and abs(a.interval_cv - b.interval_cv) <= SAME_CV and abs(a.strength - b.strength) <= SAME_STRENGTH)


def rendering_kind(profile: Any) -> type[SteadyRendering] | type[SurfaceRendering]:
    """The rendering ``profile`` names for a picture (its class: :attr:`~Rendering.name` and
    :attr:`~Rendering.reads_surface` are known before any picture is read)."""
    return SurfaceRendering if getattr(profile, "rendering", "steady") == "surface" else SteadyRendering


def rendering_for(profile: Any, surface: SurfaceLike | None = None, *, image: Any = None,
                  material: Any = None, relief_rms_m: float | None = None,
                  previous: Rendering | None = None) -> Rendering:
    """The rendering ``profile`` names, for one picture.

    Parameters
    ----------
    profile : Profile
        Its ``rendering`` (``steady`` or ``surface``) picks the rendering (:func:`rendering_kind`).
    surface : SurfaceLike, optional
        The picture as a surface, when the caller has it.
    image : TextureImage or callable, optional
        The picture (or a callable returning it, called only when needed): a surface rendering
        without ``surface`` makes the surface from it (at the profile's tip radius, of
        ``material`` and with the relief RMS ``relief_rms_m`` [m] when given:
        :func:`~tactilize.surface.surface_model`).
    previous : Rendering, optional
        The rendering in use: kept, with ``profile``, when ``profile`` renders the same picture
        the same way (a stroke under way keeps what it fired).

    Returns
    -------
    Rendering
        A surface profile given neither a surface nor an image renders steadily (its laws).
    """
    kind = rendering_kind(profile)
    if kind.reads_surface and surface is None and image is not None:
        from .model import surface_model

        surface = surface_model(image() if callable(image) else image, tip_radius_m=profile.tip_radius_m,
                                material=material, relief_rms_m=relief_rms_m)
    if surface is None:
        kind = SteadyRendering
    if type(previous) is kind and previous.surface is surface:
        previous.profile = profile
        return previous
    return kind(profile, surface)  # type: ignore[arg-type]


def rendered_drive(profile: Any, image: Any, features: Any, speed_m_s: float,
                   direction_rad: float | None = None, *, surface: Any = None) -> Drive:
    """The drive ``profile`` renders for a picture stroked steadily at ``speed_m_s`` [m/s]:
    :meth:`Rendering.steady_drive` of :func:`rendering_for` the picture (``image``, or its
    ``surface`` when the caller has it)."""
    return rendering_for(profile, surface, image=image).steady_drive(features, speed_m_s, direction_rad)


def surface_stroke_drive(surface: SurfaceLike, profile: Any, speed_m_s: float, direction_rad: float | None = None,
                         pressure: float | None = None) -> tuple[Drive, list[PulseEvent], EventStatistics]:
    """The events the pen fires over a steady :func:`~.straight.straight_stroke` on ``surface``
    (mirrored beyond its edges; the one whole-stroke path, :func:`~.playback.play_stroke`,
    through the profile's surface rendering), their statistics over the whole stroke and their
    equivalent Drive (:func:`~.equivalent.drive_of_statistics`)."""
    from .equivalent import drive_of_statistics
    from .playback import play_stroke
    from .samples import PenSample

    if speed_m_s <= 0:
        return Drive.off(), [], event_statistics([])
    t, x, y = straight_stroke(surface.width_m, surface.height_m, speed_m_s, direction_rad or 0.0)
    samples = [PenSample(a, b, c, pressure) for a, b, c in zip(t.tolist(), x.tolist(), y.tolist())]
    events = list(play_stroke(SurfaceRendering(profile, MirroredSurface(surface)), samples).events)
    stats = event_statistics(events, float(t[-1]))
    return drive_of_statistics(stats, profile), events, stats


def stroke_events(
    surface: Any,
    t_s: Sequence[float] | np.ndarray,
    x_m: Sequence[float] | np.ndarray,
    y_m: Sequence[float] | np.ndarray,
    pressure: float | None = None,
) -> list[PulseEvent]:
    """Every pulse the surface rendering fires over a whole stroke: the one whole-stroke path
    (:func:`~.playback.play_stroke`) with the page's batches, through a surface rendering of
    ``surface`` without a profile.

    Parameters
    ----------
    surface : SurfaceModel or CompositeSurface
    t_s : sequence of float
        Sample times [s], increasing.
    x_m, y_m : sequence of float
        Sample positions [display m] from the picture's top-left, y down.
    pressure : float, optional
        Pen pressure in [0, 1] for the whole stroke; None when unknown.
    """
    from .playback import play_stroke
    from .samples import PenSample

    samples = [PenSample(float(t), float(x), float(y), pressure) for t, x, y in zip(t_s, x_m, y_m)]
    return list(play_stroke(SurfaceRendering(None, surface), samples).events)
