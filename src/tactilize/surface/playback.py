"""A whole stroke through a rendering, batch by batch, as the pen's page sends it: the one path.

:func:`play_stroke` cuts a stroke's samples into the page's batches (``batch_s``, on a grid
from the first sample), lets each arrive ``transport_s`` after its newest sample, runs the
pen tracker (:class:`~.tracker.StrokeTracker`), looks the features up under the pen and asks
the :class:`~.rendering.Rendering` for the batch's frame, exactly as the pen's renderer
(:class:`tactilize.pen.PenRenderer`) does in real time.  It plays the frames as an output
that plays events does: each frame replaces the events not yet fired, and an event fires once
the output's clock reaches it (the stroke's clock mapped by the least lag,
:class:`~.clock.StrokeClock`).  It returns the events that fired and each frame's drive.

Every consumer of a whole stroke reads this: the straight stroke's drive (the catalogue's
rows, :func:`~.rendering.surface_stroke_drive`), the exports (their wire column and their
events), the serial report (the frames through the real serial output), the pen's replay
(:mod:`tactilize.pen.replay`).  A steady rendering's frames are its regular train, so its
fired events are that train.  Deterministic: no wall clock.

Units: SI (s, m).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Callable, NamedTuple, Protocol, Sequence

from .clock import StrokeClock
from .events import PulseEvent
from .tracker import StrokeState, StrokeTracker

if TYPE_CHECKING:
    from ..drive import Drive

__all__ = ["play_stroke", "PlayedStroke", "Everywhere", "stroke_batches", "BATCH_S", "TRANSPORT_S"]

#: The pen page's batch period [s] (its samples reach the host in batches this long).
BATCH_S = 0.004
#: Host to output, each batch [s] (a frame or two of USB full speed, a local socket).
TRANSPORT_S = 0.001


class Frame(Protocol):
    """What the loop reads of a frame (:class:`~.rendering.Frame` is one)."""

    @property
    def events(self) -> tuple[PulseEvent, ...]: ...

    @property
    def drive(self) -> Drive: ...

    @property
    def regular(self) -> bool: ...


class Rendering(Protocol):
    """What the loop asks of a rendering (:class:`~.rendering.Rendering` is one; this module
    sits below it, so a rendering may play a stroke of its own)."""

    def frame(self, state: StrokeState, features: Any, batch: Sequence[Any],
              played_until_s: float | None = None) -> Frame: ...

    def reset(self) -> None: ...


class PictureLookup(Protocol):
    """The features under the pen: ``lookup(x_m, y_m)`` [m, y down], None off the picture."""

    def lookup(self, x_m: float, y_m: float) -> Any: ...


class Everywhere:
    """A picture with one set of ``features`` everywhere (and no edge)."""

    def __init__(self, features: Any) -> None:
        self.features = features

    def lookup(self, x_m: float, y_m: float) -> Any:
        return self.features


class PlayedStroke(NamedTuple):
    """What a stroke's rendering played.

    Attributes
    ----------
    events : tuple of PulseEvent
        The events that fired, in time order, on the stroke's clock [s] (the output plays
        each ``transport_s`` later on its own).
    t_s : tuple of float
        Each batch's newest sample time [s].
    drives : tuple of Drive or None
        Each batch's frame's drive (None where nothing was rendered: before the tracker has
        a sample, off the picture).
    regular : tuple of (Drive, bool)
        For each fired event, the drive of the frame that handed it and whether that frame was
        its drive's regular train.
    """

    events: tuple[PulseEvent, ...]
    t_s: tuple[float, ...]
    drives: tuple[Drive | None, ...]
    regular: tuple[tuple[Drive, bool], ...] = ()


def stroke_batches(samples: Sequence[Any], batch_s: float) -> list[list[Any]]:
    """``samples`` (times increasing) cut into batches of ``batch_s`` [s] on a grid from the first
    sample's time (at least one sample per batch, whatever the rounding); empty ones left out."""
    out: list[list[Any]] = []
    n = len(samples)
    if not n:
        return out
    t0 = samples[0].t_s

    def slot(t: float) -> int:
        # (a sample on a boundary, to float rounding, opens the next batch)
        return math.floor((t - t0) / batch_s + 1e-6)

    i = 0
    while i < n:
        k = slot(samples[i].t_s)
        j = i + 1
        while j < n and slot(samples[j].t_s) == k:
            j += 1
        out.append(list(samples[i:j]))
        i = j
    return out


#: ``on_frame(batch, state, features, frame, arrival_s)``: a frame as it is handed to an output
#: (``state``, ``features`` and ``frame`` None where nothing is rendered); ``arrival_s`` [s] is
#: when the batch reaches the host, on the stroke's clock plus ``transport_s``.
OnFrame = Callable[[list[Any], "StrokeState | None", Any, "Frame | None", float], None]


def play_stroke(rendering: Rendering, samples: Sequence[Any], picture: PictureLookup | None = None, *,
                batch_s: float = BATCH_S, transport_s: float = TRANSPORT_S, tracker: StrokeTracker | None = None,
                on_frame: OnFrame | None = None) -> PlayedStroke:
    """Feed a whole stroke through ``rendering`` as the pen's page and renderer do (module docstring).

    Parameters
    ----------
    rendering : Rendering
        :func:`~.rendering.rendering_for` the picture and profile; it is reset at the end (a lift).
    samples : sequence of PenSample
        The stroke (times [s] increasing, positions [display m], y down).
    picture : PictureLookup, optional
        The features under the pen; off the picture nothing is rendered and what was pending is
        withdrawn.  None: no features (a surface rendering reads none).
    batch_s : float
        The page's batch period [s].
    transport_s : float
        Each batch reaches the output this long after its newest sample [s].
    tracker : StrokeTracker, optional
        The pen tracker (a fresh one by default).
    on_frame : callable, optional
        Called with each batch's frame (see :data:`OnFrame`): where an output plays it.

    Returns
    -------
    PlayedStroke
        An event still pending after the last batch fires only if it is due by the last
        sample (handed late, played at once): the hand went no further.
    """
    tracker = tracker or StrokeTracker()
    clock = StrokeClock()
    fired: list[tuple[PulseEvent, Drive, bool]] = []
    pending: tuple[PulseEvent, ...] = ()
    handed: Frame | None = None
    times: list[float] = []
    drives: list[Drive | None] = []
    now = -math.inf
    for batch in stroke_batches(samples, batch_s):
        now = batch[-1].t_s
        arrival = now + transport_s
        played = clock.played_until_s(now, arrival)
        if handed is not None:
            fired.extend((e, handed.drive, handed.regular) for e in pending if e.t_s <= played)
        pending, handed = (), None
        state = tracker.extend(batch)
        feat = None
        frame = None
        if state is not None and (picture is None or (feat := picture.lookup(state.x_m, state.y_m)) is not None):
            frame = rendering.frame(state, feat, batch, played)
            pending, handed = frame.events, frame
        else:
            rendering.reset()
        times.append(now)
        drives.append(None if frame is None else frame.drive)
        if on_frame is not None:
            on_frame(batch, state, feat, frame, arrival)
    if handed is not None:
        fired.extend((e, handed.drive, handed.regular) for e in pending if e.t_s <= now)
    rendering.reset()
    fired.sort(key=lambda f: f[0].t_s)
    return PlayedStroke(tuple(f[0] for f in fired), tuple(times), tuple(drives), tuple((f[1], f[2]) for f in fired))
