"""A stroke's path on a grid fixed in arc length, kept between pen batches.

The profile a stylus feels is the tip-filtered height at equal steps of arc
along its path (:mod:`.bumps`).  :class:`PathGrid` places those points at
``k * step`` of the stroke's arc length (which only grows, through stops and
reversals), so a point once behind the newest sample never moves: each batch
adds the points of its own new segments and looks their heights up once, keeps
:data:`HISTORY_M` of them, and samples only the prediction ahead afresh
(docs/surfaces.md, "Along the stroke, in real time").  :meth:`PathGrid.window`
is then exactly what resampling the whole path every batch would give.

On one picture (a :class:`~tactilize.surface.model.SurfaceModel`) the window's
prediction, heights and bumps are one compiled pass (:func:`._kernels.search_window`);
on anything else (a composite of pictures) its ``regions`` gives the heights and
:func:`._kernels.bumps_into` the bumps.  Either is exactly what
:func:`~tactilize.surface.bumps.bumps_in` finds on the same profile.

Segments are straight between samples, and a segment's time runs from the
sample before it: a pen that rests and then moves on leaves at the end of the
rest, not at its start.

Units: SI (s, m); heights in luminance units.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import _kernels
from .bumps import bumps_in
from .model import SurfaceModel

__all__ = ["PathGrid", "HISTORY_M", "Window"]

#: Path kept behind the pen [m]: a bump's prominence needs the profile around it.
HISTORY_M = 4e-3


class Window:
    """The profile a batch searches: the kept points, then the predicted ones.

    Made from arrays (a reference computation) or, by :meth:`PathGrid.window`, as a
    view of the grid's buffers with its bumps already searched.

    Attributes
    ----------
    h, ids, floors : ndarray
        Heights, region ids and prominence floors at every point (:meth:`SurfaceModel.regions`).
    k0 : int
        Grid index of the first point: point ``i`` is at arc ``(k0 + i) * step`` [m].
    kept : int
        How many of the points are behind the newest sample (the rest are predicted).
    """

    __slots__ = ("_h", "_ids", "_fl", "_t", "_a", "_stop", "k0", "kept", "step", "_found")
    _t: np.ndarray
    _found: tuple[np.ndarray, np.ndarray, np.ndarray] | None

    def __init__(self, h, ids, floors, k0, kept, t_kept, t_pred, step) -> None:
        self._h, self._ids, self._fl = h, ids, floors
        self._t = np.concatenate((np.asarray(t_kept, dtype=np.float64), np.asarray(t_pred, dtype=np.float64)))
        self._a, self._stop = 0, len(h)
        self.k0, self.kept, self.step = k0, kept, step
        self._found = None

    @classmethod
    def _of(cls, grid: "PathGrid", a: int, stop: int, kept: int, found: tuple) -> "Window":
        """Points ``a .. stop - 1`` of ``grid``'s buffers, ``found`` = (indices, prominences, times) of its bumps."""
        w = object.__new__(cls)
        w._h, w._ids, w._fl, w._t = grid._h, grid._id, grid._fl, grid._t
        w._a, w._stop, w.kept, w.step, w._found = a, stop, kept, grid.step, found
        w.k0 = grid._k0 + a
        return w

    @property
    def h(self) -> np.ndarray:
        return self._h[self._a : self._stop]

    @property
    def ids(self) -> np.ndarray:
        return self._ids[self._a : self._stop]

    @property
    def floors(self) -> np.ndarray:
        return self._fl[self._a : self._stop]

    def t_at(self, i: int) -> float:
        """Time [s] the path reaches point ``i``."""
        return float(self._t[self._a + i])

    def s_at(self, i: int) -> float:
        """Arc length [m] of point ``i``."""
        return (self.k0 + i) * self.step

    def bumps(self) -> tuple[np.ndarray, np.ndarray]:
        """(indices, prominences) of the profile's bumps (:func:`~tactilize.surface.bumps.bumps_in`)."""
        idx, prom, _ = self._search()
        return idx, prom

    def bump_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """The bumps for a compiled pass: indices, prominences, times [s], and the floors'
        buffer with the offset of point 0 in it (point ``i``'s floor is ``floors[offset + i]``)."""
        idx, prom, t = self._search()
        return idx, prom, t, self._fl, self._a

    def _search(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._found is None:
            idx, prom = bumps_in(self.h, self.ids, self.floors)
            self._found = (idx, prom, self._t[self._a + np.asarray(idx, dtype=np.intp)])
        return self._found


def warm() -> None:
    """Make the window's compiled search ready in this process (:func:`._kernels.warm`): once,
    at the first :class:`PathGrid` or when a server starts, never on a pen batch."""
    global _warm
    if not _warm:
        _kernels.warm()
        _warm = True


_warm = False


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

    def __init__(self, surface: Any, history_m: float = HISTORY_M) -> None:
        warm()
        self.surface = surface
        self.step = float(surface.step_m)
        self.history_m = float(history_m)
        self._one: tuple[np.ndarray, float, float, float] | None = None
        if isinstance(surface, SurfaceModel) and surface.micro is None:
            # The one-picture pass reads the picture directly (a material's micro-roughness
            # is drawn by the picture's own lookup, as a composite's heights are).
            self._one = (*surface.lookup_table(), float(surface.prominence_floor))
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
        # The search's output: bumps' indices and prominences (at most one every other point).
        self._oi = np.zeros(cap, dtype=np.intp)
        self._op = np.zeros(cap)
        self._ot = np.zeros(cap)  # and their times
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
        # Floats, whatever the caller passed: an integer time would make the compiled passes
        # compile again for it on a pen batch (seconds, once).
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
            None before the first sample; its bumps already searched.
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
        one = self._one
        if one is not None:
            count = _kernels.search_window(
                one[0], one[1], one[2], one[3], self._t, self._x, self._y, self._h, self._id, self._fl,
                n, end, npred, k1, step, t0, x0, y0, s0, ux, uy, speed_m_s, a, self._oi, self._op, self._ot)
        else:
            if npred:
                _kernels.predict_into(self._t, self._x, self._y, end, npred, k1, step, t0, x0, y0, s0, ux, uy,
                                      speed_m_s)
            if stop > n:
                h, ids, fl = self.surface.regions(self._x[n:stop], self._y[n:stop])
                self._h[n:stop], self._id[n:stop], self._fl[n:stop] = h, ids, fl
            count = _kernels.bumps_into(self._h, self._id, self._fl, a, stop, self._oi, self._op)
            self._ot[:count] = self._t[a + self._oi[:count]]
        self._n, self._m = end, 0
        return Window._of(self, a, stop, end - a, (self._oi[:count], self._op[:count], self._ot[:count]))
