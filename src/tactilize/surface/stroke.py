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
from typing import Any, Iterable

import numpy as np

from . import _stroke_kernels
from ._stroke_kernels import CLUSTER, LATE, MERGED, RATE_ONLY, fire_due, place_crossings, window_stats
from .events import (CLUSTER_INTERVAL_S, MIN_INTERVAL_S, RATE_ONLY_HZ, PulseEvent, full_prominence,
                     pressure_scale)
from .path import HISTORY_M, PathGrid
from .path import warm as path_warm

__all__ = ["SurfaceStroke", "LOOKAHEAD_S", "HISTORY_M", "LATE_S", "warm"]

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
#: before this rule, 16 after).
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


def _names(flags: int) -> tuple[str, ...]:
    """A PulseEvent's ``clamped`` for :func:`._stroke_kernels.place_crossings`' flags, in the order
    :func:`.events.place_events` and the late rule add them."""
    return tuple(name for bit, name in ((RATE_ONLY, "rate_only"), (CLUSTER, "cluster"), (MERGED, "merged"),
                                        (LATE, "late")) if flags & bit)


_CLAMPED = tuple(_names(f) for f in range(16))
#: The same, sorted (the equivalent Drive's ``clamped``: every name in its window).
_SORTED = tuple(tuple(sorted(c)) for c in _CLAMPED)


def warm() -> None:
    """Make every compiled pass of the pen's surface path ready in this process (the window's search,
    the stroke's bookkeeping): once, at the first stroke or when a server starts, never on a pen batch."""
    global _warm
    path_warm()
    if not _warm:
        _stroke_kernels.warm()
        _warm = True


_warm = False


class SurfaceStroke:
    """One stroke's events over a surface, batch by batch.

    Parameters
    ----------
    surface : SurfaceModel or CompositeSurface
        What is under the pen (display coordinates).
    lookahead_s : float
        Prediction horizon [s].
    """

    def __init__(self, surface: Any, lookahead_s: float = LOOKAHEAD_S) -> None:
        self.surface = surface
        self.lookahead_s = float(lookahead_s)
        self._path = PathGrid(surface)
        tip = getattr(surface, "tip_radius_m", 0.25e-3) / max(getattr(surface, "surface_per_display", 1.0), 1e-12)
        self._same_m = SAME_BUMP_SHARE * tip
        self._full = full_prominence(surface)  # a surface in metres has its own
        warm()
        # Rows: time [s], strength, flags, arc [m]: events handed out and due, the newest
        # FIRED_KEPT in a ring, and those handed out by the latest batch, not yet due.
        self._ring = np.zeros((4, FIRED_KEPT))
        self._nfired = 0  # fired so far (the ring holds the newest)
        self._pend = np.zeros((4, 16))
        self._npend = 0
        self._stats = np.zeros(5)
        self._last_fired_t = math.nan
        self.now_s: float | None = None
        #: Pulses that became due with the latest update (handed out before, due by now).
        self.newly_fired = 0

    def reset(self) -> None:
        """Forget the stroke (lift, a new picture)."""
        self._path.reset()
        self._nfired = 0
        self._npend = 0
        self._last_fired_t = math.nan
        self.now_s = None

    def update(
        self,
        samples: Iterable[Any],
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
        # What was handed out and is due by now (by the output's clock) has fired.
        self.newly_fired = 0
        if self._npend:
            played = now if played_until_s is None or played_until_s < now else played_until_s
            before = self._nfired
            self._nfired, self._last_fired_t = fire_due(self._pend, self._npend, played, self._ring, before,
                                                        self._last_fired_t)
            self.newly_fired = self._nfired - before
            self._npend = 0
        moving = direction_rad is not None and speed_m_s > STILL_SPEED_M_S
        w = path.window(speed_m_s, direction_rad if moving else None, self.lookahead_s, MAX_AHEAD_M)
        if w is None:
            return []
        idx, prom, tc, floors, fl0 = w.bump_arrays()
        count = idx.shape[0]
        if not count:
            return []
        late = now - LATE_S if previous is None else now - min(LOOKAHEAD_S, max(LATE_S, now - previous))
        scale = pressure_scale(pressure)
        if count > self._pend.shape[1]:
            self._pend = np.zeros((4, 2 * count))
        pend = self._pend
        # Every fired arc in the ring is checked: those behind this window can never match.
        n = place_crossings(
            idx, prom, tc, floors, fl0, w.k0, w.step, self._ring, min(self._nfired, FIRED_KEPT), self._same_m,
            late, now, scale, self._last_fired_t, self._full, RATE_ONLY_HZ, MIN_INTERVAL_S, CLUSTER_INTERVAL_S,
            pend)
        self._npend = n
        if not n:
            return []
        clamped = _CLAMPED
        return [PulseEvent(t, st, clamped[int(f)])
                for t, st, f in zip(pend[0, :n].tolist(), pend[1, :n].tolist(), pend[2, :n].tolist())]

    def recent(self, window_s: float) -> list[PulseEvent]:
        """Events fired in the last ``window_s`` [s] before the newest sample (oldest first), and
        those scheduled."""
        if self.now_s is None:
            return []
        since = self.now_s - window_s
        nr = min(self._nfired, FIRED_KEPT)
        order = [(self._nfired - nr + j) % FIRED_KEPT for j in range(nr)]
        cols = [(self._ring, c) for c in order] + [(self._pend, k) for k in range(self._npend)]
        return [PulseEvent(float(a[0, c]), float(a[1, c]), _CLAMPED[int(a[2, c])]) for a, c in cols
                if a[0, c] >= since]

    def window_statistics(self, window_s: float) -> tuple[int, float, float, float, tuple[str, ...]]:
        """:func:`~.equivalent.window_statistics` of :meth:`recent` events, without making them:
        count, rate [1/s], intervals' CV, mean strength and the names that clamped them."""
        if self.now_s is None:
            return 0, 0.0, 0.0, 0.0, ()
        out = self._stats
        window_stats(self._ring, self._nfired, self._pend, self._npend, self.now_s - window_s, window_s, out)
        n, rate, cv, strength, flags = out.tolist()
        return int(n), rate, cv, strength, _SORTED[int(flags)]

    def rest(self) -> list[PulseEvent]:
        """The pen rests: nothing more is predicted, what was pending is withdrawn."""
        self._npend = 0
        return []
