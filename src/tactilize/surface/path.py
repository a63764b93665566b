"""A stroke's path on a grid fixed in arc length, kept between pen batches.

The profile a stylus feels is the tip-filtered height at equal steps of arc
along its path (:mod:`.bumps`).  :class:`PathGrid` places those points at
``k * step`` of the stroke's arc length (which only grows, through stops and
reversals), so a point once behind the newest sample never moves: each batch
adds the points of its own new segments and looks their heights up once, keeps
:data:`HISTORY_M` of them, and samples only the prediction ahead afresh
(docs/surfaces.md, "Along the stroke, in real time").  :meth:`PathGrid.window`
is then exactly what resampling the whole path every batch would give.

The window's heights come from the surface's ``regions`` and its bumps from
:func:`~tactilize.surface.bumps.bumps_in`, the one bump search: a window is a few
dozen points, searched in tens of microseconds, well inside a pen batch.

Segments are straight between samples, and a segment's time runs from the
sample before it: a pen that rests and then moves on leaves at the end of the
rest, not at its start.

Units: SI (s, m); heights in luminance units.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .bumps import bumps_in
from .model import SurfaceLike

__all__ = ["PathGrid", "HISTORY_M", "Window"]

#: Path kept behind the pen [m]: a bump's prominence needs the profile around it.
HISTORY_M = 4e-3


class Window(NamedTuple):
    """The profile a batch searches: the kept points, then the predicted ones.

    Attributes
    ----------
    h, ids, floors : ndarray
        Heights, region ids and prominence floors at every point (the surface's ``regions``).
    k0 : int
        Grid index of the first point: point ``i`` is at arc ``(k0 + i) * step`` [m].
    kept : int
        How many of the points are behind the newest sample (the rest are predicted).
    t_s : ndarray
        Time [s] the path reaches each point.
    step : float
        The grid's step [m].
    """

    h: np.ndarray
    ids: np.ndarray
    floors: np.ndarray
    k0: int
    kept: int
    t_s: np.ndarray
    step: float

    def t_at(self, i: int) -> float:
        """Time [s] the path reaches point ``i``."""
        return float(self.t_s[i])

    def s_at(self, i: int) -> float:
        """Arc length [m] of point ``i``."""
        return (self.k0 + i) * self.step

    def bumps(self) -> tuple[np.ndarray, np.ndarray]:
        """(indices, prominences) of the profile's bumps (:func:`~tactilize.surface.bumps.bumps_in`)."""
        return bumps_in(self.h, self.ids, self.floors)


class PathGrid:
    """The points ``k * step`` of arc along a stroke, the newest :data:`HISTORY_M` of them kept.

    Parameters
    ----------
    surface : SurfaceModel or CompositeSurface
        Answers ``regions(x, y)`` and gives ``step_m``.
    history_m : float
        Path kept behind the newest sample [m].

    Notes
    -----
    One set of buffers holds, in grid order: the points whose heights are known
    (``_n`` of them, from grid index ``_k0``), the points this batch added (``_m``),
    and, while a window is searched, the predicted points after them.
    """

    def __init__(self, surface: SurfaceLike, history_m: float = HISTORY_M) -> None:
        self.surface = surface
        self.step = float(surface.step_m)
        self.history_m = float(history_m)
        span = int(self.history_m / self.step) + 2
        self._alloc(4 * span + 256)
        self.reset()

    def _alloc(self, cap: int) -> None:
        """Buffers for ``cap`` points (what they held is kept): t, x, y, heights, regions, floors."""
        old = getattr(self, "_bufs", ())
        bufs = tuple(np.zeros(cap, dtype=np.intp if i == 4 else np.float64) for i in range(6))
        for a, b in zip(old, bufs):
            b[: a.size] = a
        self._bufs = bufs
        self._t, self._x, self._y, self._h, self._id, self._fl = bufs
        self._cap = cap

    def reset(self) -> None:
        """Forget the path."""
        #: The newest sample (t [s], x [m], y [m], arc [m]), or None.
        self.last: tuple[float, float, float, float] | None = None
        self._k0 = 0  # grid index of buffer slot 0
        self._n = 0  # points with heights
        self._m = 0  # points after them, heights not yet looked up

    def _room(self, need: int) -> None:
        """Make the buffers hold ``need`` points: slide off what no window can reach again
        (behind :data:`HISTORY_M`), grow if that is not enough."""
        s0 = self.last[3]  # type: ignore[index]
        n, m = self._n, self._m
        i0 = min(n, max(0, math.ceil((s0 - self.history_m) / self.step) - self._k0))
        if i0:
            for a in self._bufs:
                a[: n + m - i0] = a[i0 : n + m]
            self._k0 += i0
            self._n = n - i0
            need -= i0
        if need > self._cap:
            self._alloc(max(need, 2 * self._cap))

    def add(self, t: float, x: float, y: float) -> None:
        """A sample whose time is after the newest one's [s, m]: its segment's points join the path."""
        t, x, y = float(t), float(x), float(y)
        last = self.last
        if last is None:
            self.last = (t, x, y, 0.0)
            self._k0, self._n, self._m = 0, 0, 1
            self._t[0], self._x[0], self._y[0] = t, x, y
            return
        t0, x0, y0, s0 = last
        d = math.hypot(x - x0, y - y0)
        if d <= 0:
            self.last = (t, x, y, s0)  # at rest: the next segment leaves now
            return
        s1 = s0 + d
        self.last = (t, x, y, s1)
        step = self.step
        k_end = math.floor(s1 / step)
        k = math.floor(s0 / step) + 1
        lo = math.ceil((s1 - self.history_m) / step)
        if lo > k:
            # A jump longer than the history: only its end is kept, and nothing before it.
            k = lo
            self._k0, self._n, self._m = lo, 0, 0
        if k > k_end:
            return
        j = self._n + self._m
        if j == 0:
            self._k0 = k
        if j + k_end - k + 1 > self._cap:
            self._room(j + k_end - k + 1)
            j = self._n + self._m
        tb, xb, yb = self._t, self._x, self._y
        dt, dx, dy = (t - t0) / d, (x - x0) / d, (y - y0) / d
        for kk in range(k, k_end + 1):
            a = kk * step - s0
            tb[j], xb[j], yb[j] = t0 + a * dt, x0 + a * dx, y0 + a * dy
            j += 1
        self._m = j - self._n

    def window(self, speed_m_s: float, direction_rad: float | None, lookahead_s: float,
               max_ahead_m: float = math.inf) -> Window | None:
        """The profile from :data:`HISTORY_M` behind the newest sample to the prediction's end.

        Parameters
        ----------
        speed_m_s, direction_rad : float
            The velocity the path is predicted with [m/s, rad (y up)]; direction None: no prediction.
        lookahead_s : float
            How far ahead [s].
        max_ahead_m : float
            ...but never more than this far [m].

        Returns
        -------
        Window or None
            None before the first sample.
        """
        last = self.last
        if last is None:
            return None
        t0, x0, y0, s0 = last
        step = self.step
        if direction_rad is not None and speed_m_s > 0:
            k1 = math.floor(s0 / step) + 1
            k2 = math.floor((s0 + min(speed_m_s * lookahead_s, max_ahead_m)) / step)
            ux, uy = math.cos(direction_rad), -math.sin(direction_rad)  # y up -> y down
        else:
            k1, k2, ux, uy, speed_m_s = 0, -1, 0.0, 0.0, 1.0
        npred = max(0, k2 - k1 + 1)
        if self._n + self._m + npred > self._cap:
            self._room(self._n + self._m + npred)
        n = self._n
        end = n + self._m
        stop = end + npred
        # The window starts HISTORY_M behind the newest sample.
        a = min(end, max(0, math.ceil((s0 - self.history_m) / step) - self._k0))
        if npred:
            off = np.arange(k1, k1 + npred) * step - s0
            # x0 + ux * off (and the others), written in place: the same numbers, no temporaries.
            for buf, origin, slope in ((self._x, x0, ux), (self._y, y0, uy)):
                out = buf[end:stop]
                np.multiply(off, slope, out=out)
                np.add(out, origin, out=out)
            out = self._t[end:stop]
            np.divide(off, speed_m_s, out=out)
            np.add(out, t0, out=out)
        if stop > n:
            h, ids, fl = self.surface.regions(self._x[n:stop], self._y[n:stop])
            self._h[n:stop], self._id[n:stop], self._fl[n:stop] = h, ids, fl
        self._n, self._m = end, 0
        # Copies: the buffers slide and are written again by the next batch.
        return Window(self._h[a:stop].copy(), self._id[a:stop].copy(), self._fl[a:stop].copy(), self._k0 + a,
                      end - a, self._t[a:stop].copy(), step)
