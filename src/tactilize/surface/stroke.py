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
from typing import Any, Iterable

import numpy as np

from ._kernels import CLUSTER, LATE, MERGED, RATE_ONLY, place_crossings
from .events import (CLUSTER_INTERVAL_S, FULL_PROMINENCE, MIN_INTERVAL_S, RATE_ONLY_HZ, REFERENCE_PRESSURE,
                     PulseEvent)
from .path import HISTORY_M, PathGrid

__all__ = ["SurfaceStroke", "LOOKAHEAD_S", "HISTORY_M", "LATE_S"]

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
#: Fired pulses remembered (their arcs, to recognise a bump found again).
FIRED_KEPT = 256


def _names(flags: int) -> tuple[str, ...]:
    """A PulseEvent's ``clamped`` for :func:`._kernels.place_crossings`' flags, in the order
    :func:`.events.place_events` and the late rule add them."""
    return tuple(name for bit, name in ((RATE_ONLY, "rate_only"), (CLUSTER, "cluster"), (MERGED, "merged"),
                                        (LATE, "late")) if flags & bit)


_CLAMPED = tuple(_names(f) for f in range(16))


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
        self._fired: deque[tuple[PulseEvent, float]] = deque(maxlen=FIRED_KEPT)  # (event, s_m) handed out and due
        # The same arcs in a ring for the compiled pass (the oldest overwritten, as the deque drops it).
        self._fired_arc = np.zeros(FIRED_KEPT)
        self._nfired = 0
        self._out = tuple(np.empty(16, dtype=np.intp if i == 2 else np.float64) for i in range(4))
        self._pending: list[tuple[PulseEvent, float]] = []  # handed out, not yet due: (event, s_m)
        self._last_fired_t: float | None = None
        self.now_s: float | None = None
        #: Pulses that became due with the latest update (handed out before, due by now).
        self.newly_fired = 0

    def reset(self) -> None:
        """Forget the stroke (lift, a new picture)."""
        self._path.reset()
        self._fired.clear()
        self._nfired = 0
        self._pending = []
        self._last_fired_t = None
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
        if self._pending:
            played = now if played_until_s is None or played_until_s < now else played_until_s
            for ev, s in self._pending:
                if ev.t_s <= played:
                    self.newly_fired += 1
                    self._fired.append((ev, s))
                    self._fired_arc[self._nfired % FIRED_KEPT] = s
                    self._nfired += 1
                    self._last_fired_t = ev.t_s if self._last_fired_t is None else max(self._last_fired_t, ev.t_s)
            self._pending = []
        moving = direction_rad is not None and speed_m_s > STILL_SPEED_M_S
        w = path.window(speed_m_s, direction_rad if moving else None, self.lookahead_s, MAX_AHEAD_M)
        if w is None:
            return []
        idx, prom, tc, floors, fl0 = w.bump_arrays()
        count = idx.shape[0]
        if not count:
            return []
        same = self._same_m
        # Fired arcs behind this window's reach are let go (arc length only grows); the
        # compiled pass checks against every arc in its ring, those behind can never match.
        fired = self._fired
        start = w.k0 * w.step
        while fired and fired[0][1] < start - same:
            fired.popleft()
        late = now - LATE_S if previous is None else now - min(LOOKAHEAD_S, max(LATE_S, now - previous))
        scale = 1.0 if pressure is None else min(1.0, max(0.0, float(pressure)) / REFERENCE_PRESSURE)
        if count > self._out[0].shape[0]:
            self._out = tuple(np.empty(2 * count, dtype=np.intp if i == 2 else np.float64) for i in range(4))
        ot, os_, of, oa = self._out
        prev = self._last_fired_t
        n = place_crossings(
            idx, prom, tc, floors, fl0, w.k0, w.step, self._fired_arc, min(self._nfired, FIRED_KEPT), same, late, now, scale,
            math.nan if prev is None else prev, FULL_PROMINENCE, RATE_ONLY_HZ, MIN_INTERVAL_S, CLUSTER_INTERVAL_S,
            ot, os_, of, oa)
        if not n:
            return []
        out = []
        pending = self._pending
        for t, st, f, arc in zip(ot[:n].tolist(), os_[:n].tolist(), of[:n].tolist(), oa[:n].tolist()):
            ev = PulseEvent(t, st, _CLAMPED[f])
            out.append(ev)
            pending.append((ev, arc))
        return out

    def recent(self, window_s: float) -> list[PulseEvent]:
        """Events fired in the last ``window_s`` [s] before the newest sample, and those scheduled."""
        if self.now_s is None:
            return []
        since = self.now_s - window_s
        return [e for e, _ in self._fired if e.t_s >= since] + [e for e, _ in self._pending]

    def rest(self) -> list[PulseEvent]:
        """The pen rests: nothing more is predicted, what was pending is withdrawn."""
        self._pending = []
        return []
