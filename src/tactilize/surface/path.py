"""A stroke's path on a grid fixed in arc length, kept between pen batches.

The profile a stylus feels is the tip-filtered height at equal steps of arc
along its path (:mod:`.bumps`).  :class:`PathGrid` places those points at
``k * step`` of the stroke's arc length (which only grows, through stops and
reversals), so a point once behind the newest sample never moves: each batch
adds the points of its own new segments and looks their heights up once, keeps
:data:`HISTORY_M` of them, and samples only the prediction ahead afresh
(docs/surfaces.md, "Along the stroke, in real time").  :meth:`PathGrid.window`
is then exactly what resampling the whole path every batch would give.

Segments are straight between samples, and a segment's time runs from the
sample before it: a pen that rests and then moves on leaves at the end of the
rest, not at its start.

Units: SI (s, m); heights in luminance units.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["PathGrid", "HISTORY_M", "Window"]

#: Path kept behind the pen [m]: a bump's prominence needs the profile around it.
HISTORY_M = 4e-3


class Window:
    """The profile a batch searches: the kept points, then the predicted ones.

    Attributes
    ----------
    h, ids, floors : ndarray
        Heights, region ids and prominence floors at every point (:meth:`SurfaceModel.regions`).
    k0 : int
        Grid index of the first point: point ``i`` is at arc ``(k0 + i) * step`` [m].
    kept : int
        How many of the points are behind the newest sample (the rest are predicted).
    """

    __slots__ = ("h", "ids", "floors", "k0", "kept", "_t_kept", "_t_pred", "step")

    def __init__(self, h, ids, floors, k0, kept, t_kept, t_pred, step) -> None:
        self.h, self.ids, self.floors, self.k0, self.kept = h, ids, floors, k0, kept
        self._t_kept, self._t_pred, self.step = t_kept, t_pred, step

    def t_at(self, i: int) -> float:
        """Time [s] the path reaches point ``i``."""
        return float(self._t_kept[i] if i < self.kept else self._t_pred[i - self.kept])

    def s_at(self, i: int) -> float:
        """Arc length [m] of point ``i``."""
        return (self.k0 + i) * self.step


class PathGrid:
    """The points ``k * step`` of arc along a stroke, the newest :data:`HISTORY_M` of them kept.

    Parameters
    ----------
    surface : SurfaceModel or CompositeSurface
        Answers ``regions(x, y)`` and gives ``step_m``.
    history_m : float
        Path kept behind the newest sample [m].
    """

    def __init__(self, surface: Any, history_m: float = HISTORY_M) -> None:
        self.surface = surface
        self.step = float(surface.step_m)
        self.history_m = float(history_m)
        span = int(self.history_m / self.step) + 2
        self._cap = 4 * span + 256
        self._t = np.empty(self._cap)
        self._h = np.empty(self._cap)
        self._id = np.empty(self._cap, dtype=np.intp)
        self._fl = np.empty(self._cap)
        self.reset()

    def reset(self) -> None:
        """Forget the path."""
        #: The newest sample (t [s], x [m], y [m], arc [m]), or None.
        self.last: tuple[float, float, float, float] | None = None
        self._k0 = 0  # grid index of buffer slot 0
        self._n = 0  # points in the buffer
        self._nt: list[float] = []  # points of this batch, heights not yet looked up
        self._nx: list[float] = []
        self._ny: list[float] = []
        self._nk = 0  # grid index of the first of them

    def add(self, t: float, x: float, y: float) -> None:
        """A sample whose time is after the newest one's [s, m]: its segment's points join the path."""
        last = self.last
        if last is None:
            self.last = (t, x, y, 0.0)
            self._nk, self._nt, self._nx, self._ny = 0, [t], [x], [y]
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
            self._n, self._k0 = 0, lo
            self._nk, self._nt, self._nx, self._ny = lo, [], [], []
        if k > k_end:
            return
        nt, nx, ny = self._nt, self._nx, self._ny
        if not nt:
            self._nk = k
        dt, dx, dy = (t - t0) / d, (x - x0) / d, (y - y0) / d
        for kk in range(k, k_end + 1):
            a = kk * step - s0
            nt.append(t0 + a * dt)
            nx.append(x0 + a * dx)
            ny.append(y0 + a * dy)

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
        nn = len(self._nt)
        if direction_rad is not None and speed_m_s > 0:
            k1 = math.floor(s0 / step) + 1
            k2 = math.floor((s0 + min(speed_m_s * lookahead_s, max_ahead_m)) / step)
        else:
            k1, k2 = 0, -1
        npred = max(0, k2 - k1 + 1)
        if nn == 0 and npred == 0:
            h = ids = fl = _EMPTY_I
            t_pred = _EMPTY
        else:
            if npred:
                a = np.arange(k1, k2 + 1) * step - s0
                ux, uy = math.cos(direction_rad), -math.sin(direction_rad)  # y up -> y down
                px, py = x0 + ux * a, y0 + uy * a
                t_pred = t0 + a / speed_m_s
                if nn:
                    px = np.concatenate((self._nx, px))
                    py = np.concatenate((self._ny, py))
            else:
                px, py, t_pred = np.array(self._nx), np.array(self._ny), _EMPTY
            h, ids, fl = self.surface.regions(px, py)
            if nn:
                self._keep(h[:nn], ids[:nn], fl[:nn])
                h, ids, fl = h[nn:], ids[nn:], fl[nn:]
        # The kept points from HISTORY_M behind the newest sample.
        i0 = max(0, math.ceil((s0 - self.history_m) / step) - self._k0)
        n = self._n
        kept = n - i0
        if kept > 0:
            if npred:
                h = np.concatenate((self._h[i0:n], h))
                ids = np.concatenate((self._id[i0:n], ids))
                fl = np.concatenate((self._fl[i0:n], fl))
            else:
                h, ids, fl = self._h[i0:n], self._id[i0:n], self._fl[i0:n]
        return Window(h, ids, fl, self._k0 + i0, max(kept, 0), self._t[i0:n] if kept > 0 else _EMPTY, t_pred, step)

    def _keep(self, h: np.ndarray, ids: np.ndarray, fl: np.ndarray) -> None:
        """Store this batch's points with their heights."""
        m = len(self._nt)
        if self._n == 0:
            self._k0 = self._nk
        n = self._n
        if n + m > self._cap:
            # Slide what the window can still reach to the front (the oldest go).
            s0 = self.last[3]  # type: ignore[index]
            i0 = min(n, max(0, math.ceil((s0 - self.history_m) / self.step) - self._k0))
            for a in (self._t, self._h, self._id, self._fl):
                a[: n - i0] = a[i0:n]
            self._k0 += i0
            n -= i0
            if n + m > self._cap:  # more new points than the buffer: keep the newest
                drop = n + m - self._cap
                self._n, n = 0, 0
                self._k0 = self._nk + drop
                self._nt, h, ids, fl = self._nt[drop:], h[drop:], ids[drop:], fl[drop:]
                m -= drop
        self._t[n : n + m] = self._nt
        self._h[n : n + m] = h
        self._id[n : n + m] = ids
        self._fl[n : n + m] = fl
        self._n = n + m
        self._nt, self._nx, self._ny = [], [], []


_EMPTY = np.zeros(0)
_EMPTY_I = np.zeros(0, dtype=np.intp)
