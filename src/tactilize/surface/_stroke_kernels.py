"""The stroke's bookkeeping as compiled passes (numba): new events, fired events, the window's statistics.

A pen batch over a surface, after its window's search (:mod:`._kernels`), turns the
bumps found into pulse events, moves what the output has played among the fired
ones, and gives the output the steady equivalent of the events around now.  Each is a
handful of values, where Python's per-object work costs more than the arithmetic.

What is computed is defined by readable versions, which stay the reference and are
what the offline paths use; tests check the compiled passes against them with
hypothesis (tests/test_surface_place_kernel.py, tests/test_surface_stroke_state.py):

* :func:`place_crossings`: the stroke's rule (:mod:`.stroke`), then
  :func:`.events.strengths` and :func:`.events.place_events`;
* :func:`window_stats`: :func:`.equivalent.window_statistics` of the stroke's
  recent events.

State lives in two float64 arrays of four rows (time [s], strength, flags, arc [m]):
the fired ring (``FIRED_KEPT`` columns, the oldest overwritten) and the pending events
(the newest batch's).  Flags are :data:`RATE_ONLY` | :data:`CLUSTER` | :data:`MERGED` |
:data:`LATE`, the names a :class:`~.events.PulseEvent` carries in ``clamped``.

Units: SI (s, m); strength in [0, 1].
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["place_crossings", "fire_due", "window_stats", "RATE_ONLY", "CLUSTER", "MERGED", "LATE", "warm"]

#: Flag bits, in the order :func:`~.events.place_events` and the late rule add the names.
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


# Holding the GIL (no nogil), as the window's search: microseconds on the server's event loop.
@njit(cache=True)
def place_crossings(idx, prom, tc, floors, fl0, k0, step, ring, nring, same, late, now, scale, previous,
                    full_prominence, rate_only_hz, min_interval_s, cluster_interval_s, out):  # pragma: no cover
    """A batch's new pulse events from its window's bumps, written as columns of ``out``; returns how many.

    Bump ``c`` (window index ``idx[c]``, prominence ``prom[c]``, time ``tc[c]`` [s], floor
    ``floors[fl0 + idx[c]]``) is at arc ``(k0 + idx[c]) * step`` [m].  It is left out when its
    time is at or before ``late`` [s], or when it is within ``same`` [m] of arc of one of the
    first ``nring`` fired arcs (``ring[3]``: already played).  The rest, at ``max(t, now)``,
    sorted by time (stable), get their strengths (log scale from the floor to
    ``full_prominence``, times ``scale``) and are placed after the pulse at ``previous`` [s]
    (NaN: none) as ``place_events`` places them; :data:`LATE` marks an event at ``now`` or before.
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
        for f in range(nring):
            d = ring[3, f] - si
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
            if j == 0:  # no pulse before (off is 0)
                d = t[1] - t[0]
            elif j == m - 1:
                d = t[i] - (t[i - 1] if i > 0 else previous)
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
                    out[2, k - 1] = float(int(out[2, k - 1]) | MERGED)
                continue
            if gap < cluster_interval_s and not fast[i]:
                si *= gap / cluster_interval_s
                flags |= CLUSTER
        if ti <= now:
            flags |= LATE
        out[0, k] = ti
        out[1, k] = si
        out[2, k] = flags
        out[3, k] = arc[i]
        k += 1
        last = ti
    return k


@njit(cache=True)
def fire_due(pend, npend, played, ring, nfired, last_t):  # pragma: no cover - compiled
    """The pending events due by ``played`` [s] join the fired ring (in their order).

    ``nfired`` counts every event fired so far (the ring holds the newest ``ring.shape[1]``);
    ``last_t`` is the latest fired time [s] (NaN: none).  Returns both, updated.
    """
    cap = ring.shape[1]
    for k in range(npend):
        t = pend[0, k]
        if t <= played:
            c = nfired % cap
            for r in range(4):
                ring[r, c] = pend[r, k]
            nfired += 1
            if math.isnan(last_t) or t > last_t:
                last_t = t
    return nfired, last_t


@njit(cache=True)
def window_stats(ring, nfired, pend, npend, since, window_s, out):  # pragma: no cover - compiled
    """:func:`~.equivalent.window_statistics` of the fired events (oldest first) and the pending
    ones from ``since`` [s] on: writes count, rate [1/s], interval CV, mean strength and the
    union of flags to ``out[0:5]``; returns the count."""
    cap = ring.shape[1]
    nr = min(nfired, cap)
    first = nfired - nr
    t = np.empty(nr + npend)
    n = 0
    total = 0.0
    flags = 0
    for j in range(nr + npend):
        if j < nr:
            c = (first + j) % cap
            tj, sj, fj = ring[0, c], ring[1, c], ring[2, c]
        else:
            tj, sj, fj = pend[0, j - nr], pend[1, j - nr], pend[2, j - nr]
        if tj >= since:
            t[n] = tj
            total += sj
            flags |= int(fj)
            n += 1
    out[0] = n
    out[4] = flags
    if n == 0:
        out[1] = 0.0
        out[2] = 0.0
        out[3] = 0.0
        return 0
    ts = np.sort(t[:n])
    out[3] = total / n
    if n >= 2 and ts[n - 1] > ts[0]:
        acc = 0.0
        for i in range(n - 1):
            acc += ts[i + 1] - ts[i]
        mean = acc / (n - 1)
        if n - 1 > 1:
            sq = 0.0
            for i in range(n - 1):
                d = (ts[i + 1] - ts[i]) - mean
                sq += d * d
            cv = math.sqrt(sq / (n - 1)) / mean
        else:
            cv = 0.0
        out[1] = (n - 1) / (ts[n - 1] - ts[0])
        out[2] = cv
    else:
        out[1] = 1.0 / window_s
        out[2] = 0.0
    return n


def warm() -> None:
    """Load (or compile, the first time on a machine) the stroke's kernels for the types the pen
    path passes, so the first pen batch of a session does not wait for them."""
    f = np.zeros(8)
    i = np.zeros(2, dtype=np.intp)
    state = np.zeros((4, 8))
    place_crossings(i, f[:2] + 0.5, f[:2], f + 0.1, 0, 0, 1e-4, state, 0, 1e-4, -1.0, 0.0, 1.0, math.nan,
                    0.5, 150.0, 1 / 300, 1 / 150, state.copy())
    fire_due(state, 0, 0.0, state.copy(), 0, math.nan)
    window_stats(state, 0, state.copy(), 0, 0.0, 0.15, f.copy())
