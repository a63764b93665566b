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
from bisect import bisect_left
from collections import deque
from typing import Any, Iterable

from .bumps import crossings_along, resample_path
from .events import PulseEvent, place_events
from .events import strengths as strengths_of

__all__ = ["SurfaceStroke", "LOOKAHEAD_S", "HISTORY_M", "LATE_S"]

#: How far ahead the path is predicted [s]: more than a batch and its transport
#: (4 + 1 ms on the page), so a crossing between batches is scheduled before it
#: happens, short enough that a stop or a reversal is seen before most of its
#: predicted crossings would fire.
LOOKAHEAD_S = 0.025
#: Path kept behind the pen [m]: a bump's prominence needs the profile around it.
HISTORY_M = 4e-3
#: A crossing found this long after its time [s] still plays (at once); older is dropped.
LATE_S = 0.005
#: Two crossings within this share of the tip radius of arc are one bump.
SAME_BUMP_SHARE = 0.5
#: Longest silence within one stroke [s] (the tracker's own rule).
MAX_GAP_S = 0.1
#: Below this speed [m/s] nothing is predicted (a resting pen).
STILL_SPEED_M_S = 1e-3


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
        self._t: deque[float] = deque()
        self._x: deque[float] = deque()
        self._y: deque[float] = deque()
        self._s: deque[float] = deque()
        self._fired: deque[tuple[PulseEvent, float]] = deque(maxlen=256)  # (event, s_m) handed out and due
        self._pending: list[tuple[PulseEvent, float]] = []  # handed out, not yet due: (event, s_m)
        self._last_fired_t: float | None = None
        self.now_s: float | None = None
        #: Pulses that became due with the latest update (handed out before, due by now).
        self.newly_fired = 0

    def reset(self) -> None:
        """Forget the stroke (lift, a new picture)."""
        for q in (self._t, self._x, self._y, self._s):
            q.clear()
        self._fired.clear()
        self._pending = []
        self._last_fired_t = None
        self.now_s = None

    def _add(self, t: float, x: float, y: float) -> None:
        if self._t:
            dt = t - self._t[-1]
            if dt <= 0:
                return
            if dt > MAX_GAP_S:
                self.reset()
        if not self._t:
            self._t.append(t), self._x.append(x), self._y.append(y), self._s.append(0.0)
            return
        d = math.hypot(x - self._x[-1], y - self._y[-1])
        self._t.append(t), self._x.append(x), self._y.append(y), self._s.append(self._s[-1] + d)
        # Keep HISTORY_M of path behind the newest sample (and at least two samples).
        while len(self._s) > 2 and self._s[-1] - self._s[1] > HISTORY_M:
            for q in (self._t, self._x, self._y, self._s):
                q.popleft()

    def update(
        self,
        samples: Iterable[Any],
        speed_m_s: float,
        direction_rad: float | None,
        pressure: float | None = None,
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

        Returns
        -------
        list of PulseEvent
            Times [s] on the stroke's clock; an event found up to :data:`LATE_S`
            late is given at the newest sample's time, marked ``late``.
        """
        for smp in samples:
            if math.isfinite(smp.t_s) and math.isfinite(smp.x_m) and math.isfinite(smp.y_m):
                self._add(smp.t_s, smp.x_m, smp.y_m)
        if not self._t:
            return []
        now = self._t[-1]
        self.now_s = now
        # What was handed out and is due by now has fired.
        self.newly_fired = 0
        keep = []
        for ev, s in self._pending:
            if ev.t_s <= now:
                self.newly_fired += 1
                self._fired.append((ev, s))
                self._last_fired_t = ev.t_s if self._last_fired_t is None else max(self._last_fired_t, ev.t_s)
            else:
                keep.append((ev, s))
        self._pending = []
        t, x, y = list(self._t), list(self._x), list(self._y)
        moving = direction_rad is not None and speed_m_s > STILL_SPEED_M_S
        if moving:
            dx = speed_m_s * math.cos(direction_rad) * self.lookahead_s
            dy = -speed_m_s * math.sin(direction_rad) * self.lookahead_s  # y up -> y down
            t.append(now + self.lookahead_s), x.append(x[-1] + dx), y.append(y[-1] + dy)
        if len(t) < 2:
            return []
        path = resample_path(t, x, y, self.surface.step_m, self._s[0])
        c = crossings_along(self.surface, *path)
        if c.t_s.size == 0:
            return []
        tip = getattr(self.surface, "tip_radius_m", 0.25e-3) / max(getattr(self.surface, "surface_per_display", 1.0), 1e-12)
        same = SAME_BUMP_SHARE * tip
        # Fired arcs, in order (arc length only grows), within reach of this window.
        while self._fired and self._fired[0][1] < self._s[0] - same:
            self._fired.popleft()
        fired_s = sorted(s for _, s in self._fired)
        times, arcs, strengths = [], [], []
        st = strengths_of(c.prominence.tolist(), c.floor.tolist(), pressure)
        for ti, si, gi in zip(c.t_s.tolist(), c.s_m.tolist(), st):
            k = bisect_left(fired_s, si)
            if (k < len(fired_s) and fired_s[k] - si < same) or (k > 0 and si - fired_s[k - 1] < same):
                continue
            if ti <= now - LATE_S:
                continue  # too late to be felt as this bump
            times.append(max(ti, now))
            arcs.append(si)
            strengths.append(gi)
        if not times:
            return []
        order = sorted(range(len(times)), key=times.__getitem__)  # stable, as argsort's was
        times = [times[i] for i in order]
        arcs = [arcs[i] for i in order]
        strengths = [strengths[i] for i in order]
        events = place_events(times, strengths, previous_t_s=self._last_fired_t)
        out = []
        # place_events may drop crossings (merged): match events back to arcs by time.
        j = 0
        for ev in events:
            while j < len(times) and times[j] < ev.t_s:
                j += 1
            s_j = arcs[min(j, len(arcs) - 1)]
            if ev.t_s <= now:
                ev = ev._replace(t_s=now, clamped=ev.clamped + ("late",))
            out.append(ev)
            self._pending.append((ev, s_j))
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
