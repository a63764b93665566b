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

__all__ = ["bilinear", "heights_into", "predict_into", "bumps_into", "search_window", "place_crossings", "warm"]

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
    place_crossings(i[:2], f[:2] + 0.5, f[:2], f + 0.1, 0, 0, 1e-4, f.copy(), 0, 1e-4, -1.0, 0.0, 1.0, math.nan,
                    0.5, 150.0, 1 / 300, 1 / 150, f.copy(), f.copy(), i.copy(), f.copy())


#: Bits of :func:`place_crossings`' flags: the names a :class:`~.events.PulseEvent` carries in
#: ``clamped``, in the order :func:`~.events.place_events` and the stroke add them.
RATE_ONLY, CLUSTER, MERGED, LATE = 1, 2, 4, 8


@njit(cache=True)
def _median_around(s, i, n):  # pragma: no cover - compiled
    """``statistics.median(s[max(0, i - 3) : i + 4])`` (at most seven values)."""
    lo = max(0, i - 3)
    hi = min(n, i + 4)
    m = hi - lo
    v = np.empty(m)
    for k in range(m):  # insertion sort: seven values at most
        x = s[lo + k]
        j = k - 1
        while j >= 0 and v[j] > x:
            v[j + 1] = v[j]
            j -= 1
        v[j + 1] = x
    if m % 2 == 1:
        return v[m // 2]
    return (v[m // 2 - 1] + v[m // 2]) / 2


@njit(cache=True)
def place_crossings(idx, prom, tc, floors, fl0, k0, step, fired, nfired, same, late, now, scale, previous,
                    full_prominence, rate_only_hz, min_interval_s, cluster_interval_s,
                    out_t, out_s, out_flags, out_arc):  # pragma: no cover - compiled
    """A batch's new pulse events from its window's bumps: the stroke's rule, then
    :func:`~.events.strengths` and :func:`~.events.place_events`, in one pass.

    Bump ``c`` (window index ``idx[c]``, prominence ``prom[c]``, time ``tc[c]`` [s], floor
    ``floors[fl0 + idx[c]]``) is at arc ``(k0 + idx[c]) * step`` [m].  It is left out when its
    time is at or before ``late`` [s], or when it is within ``same`` [m] of arc of one of the
    ``nfired`` arcs in ``fired`` (already played).  The rest, at ``max(t, now)``, sorted by time
    (stable), get their strengths (log scale from the floor to ``full_prominence``, times
    ``scale``) and are placed after the pulse at ``previous`` [s] (NaN: none) as
    ``place_events`` places them.  Each event is written to ``out_t`` [s], ``out_s``,
    ``out_flags`` (:data:`RATE_ONLY` | :data:`CLUSTER` | :data:`MERGED` | :data:`LATE`, this last
    for an event at ``now`` or before) and ``out_arc`` [m]; returns how many.
    """
    count = idx.shape[0]
    t = np.empty(count)
    arc = np.empty(count)
    s = np.empty(count)
    n = 0
    for c in range(count):
        ti = tc[c]
        if ti <= late:
            continue  # too late to be felt as this bump
        si = (k0 + idx[c]) * step
        played = False
        for f in range(nfired):
            d = fired[f] - si
            if -same < d < same:
                played = True
                break
        if played:
            continue
        lo = floors[fl0 + idx[c]]
        span = math.log(max(full_prominence / lo, 1.0 + 1e-9))
        t[n] = ti if ti > now else now
        arc[n] = si
        s[n] = min(1.0, max(0.0, math.log(max(prom[c], 1e-12) / lo) / span)) * scale
        n += 1
    if n == 0:
        return 0
    ordered = True
    for i in range(1, n):
        if t[i] < t[i - 1]:
            ordered = False
            break
    if not ordered:  # path order is time order but for a reversal's edge
        o = np.argsort(t[:n], kind="mergesort")
        t[:n] = t[:n][o]
        arc[:n] = arc[:n][o]
        s[:n] = s[:n][o]
    has_prev = not math.isnan(previous)
    # Local rate above rate_only_hz at each crossing, the pulse before counted.
    fast = np.zeros(n, dtype=np.bool_)
    off = 1 if has_prev else 0
    m = n + off
    if m > 1:
        any_fast = False
        for i in range(n):
            j = off + i
            uj = t[i]
            if j == 0:  # no pulse before (off is 0)
                d = t[1] - uj
            elif j == m - 1:
                d = uj - (t[i - 1] if i > 0 else previous)
            else:
                d = (t[i + 1] - (t[i - 1] if i > 0 else previous)) / 2.0
            fast[i] = d <= 0 or 1.0 / max(d, 1e-12) > rate_only_hz
            any_fast = any_fast or fast[i]
        if any_fast:
            for i in range(n):
                if fast[i]:
                    s[i] = _median_around(s, i, n)
    k = 0
    last = previous
    for i in range(n):
        ti = t[i]
        si = s[i]
        flags = RATE_ONLY if fast[i] else 0
        if has_prev or k > 0:
            gap = ti - last
            if gap < min_interval_s:
                if k > 0:
                    out_flags[k - 1] |= MERGED
                continue
            if gap < cluster_interval_s and not fast[i]:
                si *= gap / cluster_interval_s
                flags |= CLUSTER
        if ti <= now:
            flags |= LATE
        out_t[k] = ti
        out_s[k] = si
        out_flags[k] = flags
        out_arc[k] = arc[i]
        k += 1
        last = ti
    return k
