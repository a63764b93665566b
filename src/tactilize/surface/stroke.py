"""Events along a stroke in real time: the path so far, predicted ahead, and what is not yet fired.

:class:`SurfaceStroke` takes each pen batch (the samples and the tracker's
estimate), extends the path (samples joined by straight segments), predicts it
:data:`LOOKAHEAD_S` ahead from the tracked velocity, finds the bumps on the last
:data:`HISTORY_M` of path plus the prediction, and returns the events not yet
fired (docs/surfaces.md, "Along the stroke, in real time").

Every crossing carries its arc length along the path, which keeps growing
through stops and reversals: a crossing already fired is recognised when a later
batch finds it again (within :data:`SAME_BUMP_SHARE` of the tip radius of arc),
and a predicted crossing the hand never reached is simply not found again.
Times are on the stroke's clock (the samples' own timestamps).

Units: SI (s, m).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Iterable, NamedTuple, Protocol

from .equivalent import EventStatistics, window_statistics
from .events import PulseEvent, full_prominence, place_events, strengths
from .model import SurfaceLike
from .path import HISTORY_M, PathGrid

__all__ = ["SurfaceStroke", "TimedPosition", "LOOKAHEAD_S", "HISTORY_M", "LATE_S"]

#: How far ahead the path is predicted [s]: more than a batch and its transport
#: (4 + 1 ms on the page), so a crossing between batches is scheduled before it
#: happens, short enough that a stop or a reversal is seen before most of its
#: predicted crossings would fire.
LOOKAHEAD_S = 0.025
#: A crossing found this long after its time [s] still plays (at once); older is dropped.
#: With sparse samples (a 60 Hz touch screen, a loaded page) a bump is often seen only
#: by the batch after its crossing (its prominence needs its far side, beyond the
#: prediction): then a crossing since the previous batch plays too, up to LOOKAHEAD_S
#: late, rather than leaving a ridge out (13 of 16 corduroy ridges at 60 Hz samples
#: without this rule, 16 with it).
LATE_S = 0.005
#: Two crossings within this share of the tip radius of arc are one bump.
SAME_BUMP_SHARE = 0.5
#: Longest silence within one stroke [s] (the tracker's own rule).
MAX_GAP_S = 0.1
#: Below this speed [m/s] nothing is predicted (a resting pen).
STILL_SPEED_M_S = 1e-3
#: The prediction reaches at most this far ahead [m]: a fast hand stroke (1 m/s) for the
#: look-ahead; a jump the tracker reads as faster must not predict metres of path.
MAX_AHEAD_M = 0.025
#: Fired pulses remembered (their arcs recognise a bump found again; their times, the
#: equivalent Drive's window, at most 300 pulses/s for 0.15 s).
FIRED_KEPT = 256


class TimedPosition(Protocol):
    """A pen sample as the stroke reads it (:class:`tactilize.pen.samples.PenSample` is one)."""

    @property
    def t_s(self) -> float: ...

    @property
    def x_m(self) -> float: ...

    @property
    def y_m(self) -> float: ...


class _Handed(NamedTuple):
    """An event handed out, with the arcs [m] along the stroke of its bump and of the last
    crossing merged into it (:func:`~.events.place_events`): every crossing between them is
    this pulse's."""

    event: PulseEvent
    arc_m: float
    last_arc_m: float


class SurfaceStroke:
    """One stroke's events over a surface, batch by batch.

    Parameters
    ----------
    surface : SurfaceLike
        What is under the pen (display coordinates).
    lookahead_s : float
        Prediction horizon [s].
    """

    def __init__(self, surface: SurfaceLike, lookahead_s: float = LOOKAHEAD_S) -> None:
        self.surface = surface
        self.lookahead_s = float(lookahead_s)
        self._path = PathGrid(surface)
        self._same_m = SAME_BUMP_SHARE * surface.tip_radius_m / max(surface.surface_per_display, 1e-12)
        self._full = full_prominence(surface)  # a surface in metres has its own
        # Handed out and due (the newest FIRED_KEPT), and handed out by the latest batch, not yet due.
        self._fired: deque[_Handed] = deque(maxlen=FIRED_KEPT)
        self._pending: list[_Handed] = []
        self._last_fired_t: float | None = None
        self.now_s: float | None = None
        #: Pulses that became due with the latest update (handed out before, due by now).
        self.newly_fired = 0

    def reset(self) -> None:
        """Forget the stroke (lift, a new picture)."""
        self._path.reset()
        self._fired.clear()
        self._pending = []
        self._last_fired_t = None
        self.now_s = None

    def update(
        self,
        samples: Iterable[TimedPosition],
        speed_m_s: float,
        direction_rad: float | None,
        pressure: float | None = None,
        played_until_s: float | None = None,
    ) -> list[PulseEvent]:
        """Add a batch; returns every event from the newest sample's time on that is not yet fired.

        Parameters
        ----------
        samples : iterable of PenSample
            The batch (times [s], positions [display m], y down); samples whose
            time does not increase are ignored.
        speed_m_s, direction_rad : float
            The tracker's velocity [m/s] and direction [rad, y up] (None: still).
        pressure : float, optional
            Pen pressure in [0, 1]; None when the device has none.
        played_until_s : float, optional
            The stroke time [s] the output has reached when this batch arrives, when that is
            later than its newest sample (a batch held up: :meth:`~tactilize.surface.clock.StrokeClock.played_until_s`).
            Events handed out before and due by then have fired, so a bump found again
            by this batch a little elsewhere is not scheduled a second time.

        Returns
        -------
        list of PulseEvent
            Times [s] on the stroke's clock; an event found late (up to :data:`LATE_S`,
            or since the previous batch when batches come sparser, at most
            :data:`LOOKAHEAD_S`) is given at the newest sample's time, marked ``late``.
        """
        isfinite = math.isfinite
        path = self._path
        for smp in samples:
            t, x, y = smp.t_s, smp.x_m, smp.y_m
            if isfinite(t) and isfinite(x) and isfinite(y):
                last = path.last
                if last is not None:
                    dt = t - last[0]
                    if dt <= 0:
                        continue
                    if dt > MAX_GAP_S:
                        self.reset()
                path.add(t, x, y)
        if path.last is None:
            return []
        now = path.last[0]
        previous, self.now_s = self.now_s, now
        self._fire_due(now if played_until_s is None else max(now, played_until_s))
        moving = direction_rad is not None and speed_m_s > STILL_SPEED_M_S
        # The profile is read HISTORY_M beyond the look-ahead, as far as it is kept behind: a bump's
        # prominence needs both its sides, so a bump handed out is judged on as much profile ahead
        # of it as behind (the same bumps, the same strengths, whichever way a spot is stroked);
        # only the look-ahead's crossings are handed out.
        ahead_s = self.lookahead_s + HISTORY_M / speed_m_s if moving else self.lookahead_s
        w = path.window(speed_m_s, direction_rad if moving else None, ahead_s, MAX_AHEAD_M)
        if w is None:
            return []
        idx, prom = w.bumps()
        if not idx.size:
            return []
        late = now - LATE_S if previous is None else now - min(LOOKAHEAD_S, max(LATE_S, now - previous))
        start_m = w.s_at(0) - self._same_m
        found: list[tuple[float, float, float, float]] = []  # (time [s], arc [m], prominence, floor)
        horizon = now + self.lookahead_s
        for i, p in zip(idx.tolist(), prom.tolist()):
            t = w.t_at(i)
            if t <= late or t > horizon:
                continue  # too late to be felt as this bump, or not yet due to be handed out
            arc = w.s_at(i)
            if not self._played(arc, start_m):
                found.append((max(t, now), arc, p, float(w.floors[i])))
        if not found:
            return []
        found.sort(key=lambda c: c[0])  # path order is time order but for a reversal's edge
        placed = place_events([c[0] for c in found],
                              strengths([c[2] for c in found], [c[3] for c in found], pressure, self._full),
                              previous_t_s=self._last_fired_t)
        # A placed event keeps its crossing's time; a crossing place_events dropped merged into the
        # pulse before it (this batch's, or the last one fired): its arc joins that pulse's, so a later
        # batch that finds it again, its predecessor played, does not play it as a pulse of its own.
        handed: list[_Handed] = []
        k = 0
        for c in found:
            if k < len(placed) and c[0] == placed[k].t_s:
                e = placed[k]
                handed.append(_Handed(e._replace(clamped=e.clamped + ("late",)) if e.t_s <= now else e, c[1], c[1]))
                k += 1
            elif handed:
                handed[-1] = handed[-1]._replace(last_arc_m=c[1])
            elif self._fired:
                self._fired[-1] = self._fired[-1]._replace(last_arc_m=max(self._fired[-1].last_arc_m, c[1]))
        self._pending = handed
        return [h.event for h in self._pending]

    def _fire_due(self, played_s: float) -> None:
        """What was handed out and is due by ``played_s`` [s] (the output's clock) has fired."""
        before = len(self._pending)
        due = [h for h in self._pending if h.event.t_s <= played_s]
        for h in due:
            self._fired.append(h)
            if self._last_fired_t is None or h.event.t_s > self._last_fired_t:
                self._last_fired_t = h.event.t_s
        self.newly_fired = len(due)
        if before:
            self._pending = []

    def _played(self, arc_m: float, start_m: float) -> bool:
        """``arc_m`` is within :data:`SAME_BUMP_SHARE` of the tip radius of a fired pulse's arcs (its
        bump's, and those of the crossings merged into it)."""
        same = self._same_m
        # Newest first: fired arcs grow along the stroke, so none behind ``start_m`` (the window's
        # start) can be this bump, nor any older one.
        for h in reversed(self._fired):
            if h.last_arc_m < start_m:
                return False
            if h.arc_m - same < arc_m < h.last_arc_m + same:
                return True
        return False

    def recent(self, window_s: float) -> list[PulseEvent]:
        """Events fired in the last ``window_s`` [s] before the newest sample (oldest first), and
        those scheduled."""
        if self.now_s is None:
            return []
        since = self.now_s - window_s
        return [h.event for h in (*self._fired, *self._pending) if h.event.t_s >= since]

    def window_statistics(self, window_s: float) -> EventStatistics:
        """:func:`~.equivalent.window_statistics` of the :meth:`recent` events."""
        if self.now_s is None:
            return window_statistics([], 0.0, window_s)
        return window_statistics(self.recent(window_s), self.now_s, window_s)

    def rest(self) -> list[PulseEvent]:
        """The pen rests: nothing more is predicted, what was pending is withdrawn."""
        self._pending = []
        return []
