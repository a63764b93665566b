"""The pen window's search as one compiled pass (numba).

Each pen batch asks for the bumps on a window of a few dozen points: the kept
path behind the pen and the prediction ahead (:mod:`.path`).  Written in NumPy
and SciPy that is a dozen calls (the prediction's points, ``map_coordinates``
for their heights, ``find_peaks`` for the maxima and prominences, the
concatenations), each costing more in its fixed overhead than in its
arithmetic on so few points.  Compiled, it is one call.

What is computed is defined by the readable versions, which stay the
reference and are what the offline paths use:

* heights: :meth:`SurfaceModel.regions <tactilize.surface.model.SurfaceModel.regions>`
  (``scipy.ndimage.map_coordinates``, order 1, mode ``nearest``, on the picture
  padded by one edge pixel), NaN and region -1 off the picture;
* bumps: :func:`tactilize.surface.bumps.bumps_in` (``scipy.signal.find_peaks``
  with a prominence floor, searched within runs of one region).

:func:`bilinear` repeats ``map_coordinates``' own arithmetic step by step
(weights ``1 - f`` and ``1 - (1 - f)``, products and sum in its order) and
:func:`_peaks_of_run` SciPy's plateau rule (the middle of a flat top, rounded
down) and its prominence walk, so the results are the same to the last bit;
tests/test_surface_kernels.py checks them against the references with
hypothesis.

Imported with :mod:`tactilize.surface.stroke` (the real-time path, which the
server loads at start), not by ``import tactilize``; compiled code is cached on
disk (``cache=True``) and :func:`warm` loads it for the types the pen path
uses, so no compilation lands on a pen batch.  No ``fastmath``: the heights
must round exactly as SciPy's do.

Units: positions in display metres, heights in luminance units, times in s.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["bilinear", "heights_into", "predict_into", "bumps_into", "search_window", "warm"]

_NAN = math.nan


@njit(cache=True, nogil=True)
def bilinear(field, cy, cx):  # pragma: no cover - compiled; tested through its results
    """``map_coordinates(field, [[cy], [cx]], order=1, mode="nearest", prefilter=False)``, one point.

    Parameters
    ----------
    field : float32 ndarray, shape (R, C)
    cy, cx : float
        Row and column coordinates [pixels, 0 at the first pixel's centre].
    """
    rows, cols = field.shape
    # The coordinate clamped to the array (mode "nearest"), as SciPy's map_coordinate does.
    cy = 0.0 if cy < 0.0 else (rows - 1.0 if cy > rows - 1 else cy)
    cx = 0.0 if cx < 0.0 else (cols - 1.0 if cx > cols - 1 else cx)
    fy = np.floor(cy)
    fx = np.floor(cx)
    r0 = int(fy)
    c0 = int(fx)
    wy0 = 1.0 - (cy - fy)
    wy1 = 1.0 - wy0
    wx0 = 1.0 - (cx - fx)
    wx1 = 1.0 - wx0
    # At the last row or column SciPy mirrors the second tap inside; its weight is 0 there.
    r1 = r0 + 1 if r0 + 1 < rows else max(rows - 2, 0)
    c1 = c0 + 1 if c0 + 1 < cols else max(cols - 2, 0)
    t = 0.0
    t += (np.float64(field[r0, c0]) * wy0) * wx0
    t += (np.float64(field[r0, c1]) * wy0) * wx1
    t += (np.float64(field[r1, c0]) * wy1) * wx0
    t += (np.float64(field[r1, c1]) * wy1) * wx1
    return t


@njit(cache=True, nogil=True)
def heights_into(field, inv_x, inv_y, floor, x, y, lo, hi, h, ids, floors):  # pragma: no cover - compiled
    """Heights at points ``lo .. hi - 1`` of ``x, y`` [display m], as ``SurfaceModel.regions`` gives them.

    Parameters
    ----------
    field : float32 ndarray, shape (rows + 2, cols + 2)
        The tip-filtered height padded by one edge pixel all round.
    inv_x, inv_y : float
        Pixels per display metre across and down.
    floor : float
        The picture's prominence floor, written to ``floors``.
    h, ids, floors : ndarray, written at ``lo .. hi - 1``
        Height (NaN off the picture), region (0 on it, -1 off), floor.
    """
    cols = field.shape[1] - 2
    rows = field.shape[0] - 2
    for i in range(lo, hi):
        px = x[i] * inv_x
        py = y[i] * inv_y
        floors[i] = floor
        if px >= 0.0 and px < cols and py >= 0.0 and py < rows:
            h[i] = bilinear(field, py + 0.5, px + 0.5)
            ids[i] = 0
        else:
            h[i] = _NAN
            ids[i] = -1


@njit(cache=True, nogil=True)
def predict_into(t, x, y, at, npred, k1, step, t0, x0, y0, s0, ux, uy, speed):  # pragma: no cover - compiled
    """The predicted points ``k1 .. k1 + npred - 1`` of the arc grid, written at ``at ..``.

    Point ``k`` is ``a = k * step - s0`` [m] ahead of the newest sample ``(t0, x0, y0)``
    along the unit direction ``(ux, uy)`` (y down), reached at ``t0 + a / speed`` [s].
    """
    for j in range(npred):
        a = (k1 + j) * step - s0
        x[at + j] = x0 + ux * a
        y[at + j] = y0 + uy * a
        t[at + j] = t0 + a / speed


@njit(cache=True, nogil=True)
def _peaks_of_run(h, a, b, floor, base, out_idx, out_prom, count):  # pragma: no cover - compiled
    """Bumps of ``h[a:b]`` as ``find_peaks(h[a:b], prominence=floor)`` finds them, appended at ``count``.

    Indices are written relative to ``base``; returns the new count.
    """
    i = a + 1
    last = b - 1
    while i < last:
        if h[i - 1] < h[i]:
            ahead = i + 1
            while ahead < last and h[ahead] == h[i]:
                ahead += 1
            if h[ahead] < h[i]:
                peak = (i + ahead - 1) // 2  # a plateau's middle, rounded down
                top = h[peak]
                left_min = top
                j = peak
                while j >= a and h[j] <= top:
                    if h[j] < left_min:
                        left_min = h[j]
                    j -= 1
                right_min = top
                j = peak
                while j < b and h[j] <= top:
                    if h[j] < right_min:
                        right_min = h[j]
                    j += 1
                prom = top - max(left_min, right_min)
                if floor <= prom:
                    out_idx[count] = peak - base
                    out_prom[count] = prom
                    count += 1
                i = ahead
        i += 1
    return count


@njit(cache=True, nogil=True)
def bumps_into(h, ids, floors, a, b, out_idx, out_prom):  # pragma: no cover - compiled
    """:func:`tactilize.surface.bumps.bumps_in` of ``h[a:b]``: its bumps, searched within each run of one
    region (never region -1, never a run shorter than 3 points).

    ``out_idx`` (intp) and ``out_prom`` (float64), at least ``(b - a) // 2`` long, receive
    the indices (from ``a``) and prominences in path order; returns how many.
    """
    count = 0
    r = a
    while r < b:
        region = ids[r]
        e = r + 1
        while e < b and ids[e] == region:
            e += 1
        if region >= 0 and e - r >= 3:
            count = _peaks_of_run(h, r, e, floors[r], a, out_idx, out_prom, count)
        r = e
    return count


# Holding the GIL (no nogil): it runs for microseconds on the server's event loop, and a
# release there hands the GIL to any thread waiting for it (the simulated wire's), which the
# batch then waits for, up to a switch interval or, on a loaded machine, an OS time slice.
@njit(cache=True)
def search_window(field, inv_x, inv_y, floor, t, x, y, h, ids, floors, lo, end, npred, k1, step,
                  t0, x0, y0, s0, ux, uy, speed, a, out_idx, out_prom, out_t):  # pragma: no cover - compiled
    """A pen batch's window on one picture, in one pass: the predicted points, the heights
    not yet looked up, and the bumps.

    Points ``end .. end + npred - 1`` get the prediction (:func:`predict_into`), points
    ``lo .. end + npred - 1`` their heights (:func:`heights_into`), and the bumps of
    ``a .. end + npred - 1`` are written as :func:`bumps_into` writes them, with the time
    each is reached in ``out_t``; returns how many.
    """
    if npred > 0:
        predict_into(t, x, y, end, npred, k1, step, t0, x0, y0, s0, ux, uy, speed)
    heights_into(field, inv_x, inv_y, floor, x, y, lo, end + npred, h, ids, floors)
    count = bumps_into(h, ids, floors, a, end + npred, out_idx, out_prom)
    for c in range(count):
        out_t[c] = t[a + out_idx[c]]
    return count


def warm() -> None:
    """Load (or compile, the first time on a machine) every kernel for the types the pen path
    passes, so the first pen batch of a session does not wait for it."""
    field = np.zeros((4, 4), dtype=np.float32)
    f = np.zeros(8)
    i = np.zeros(8, dtype=np.intp)
    search_window(field, 1.0, 1.0, 0.1, f, f.copy(), f.copy(), f.copy(), i, f.copy(), 0, 3, 2, 3, 0.5,
                  0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0, i.copy(), f.copy(), f.copy())
    predict_into(f, f.copy(), f.copy(), 0, 2, 0, 0.5, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0)
    bumps_into(f, i, f.copy(), 0, 8, i.copy(), f.copy())

