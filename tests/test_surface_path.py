"""The real-time path kept between batches (tactilize.surface.path) against a from-scratch computation.

:class:`PathGrid` adds each batch's new segments to a grid fixed in arc length and
samples only the prediction afresh.  Here a reference recomputes the same window
from every sample so far, every batch, with NumPy's own interpolation; both drive
a :class:`SurfaceStroke` through the same batches, and the events must be the same
batch for batch: stops, a reversal, a curve, a jump, a gap, batches of one to
nine samples, a composite of pictures.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactilize.pen.samples import PenSample
from tactilize.pen.tracker import StrokeTracker
from tactilize.surface import CompositeSurface, SurfaceStroke, surface_model
from tactilize.surface.fields import grain_field
from tactilize.surface.path import HISTORY_M, PathGrid, Window


class ScratchPath:
    """Every batch, the window recomputed from all samples (the definition PathGrid keeps)."""

    def __init__(self, surface):
        self.surface = surface
        self.step = float(surface.step_m)
        self.reset()

    def reset(self):
        self.samples: list[tuple[float, float, float]] = []
        self.last = None

    def add(self, t, x, y):
        self.samples.append((t, x, y))
        a = np.array(self.samples)
        s = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(a[:, 1]), np.diff(a[:, 2])))))
        self.last = (t, x, y, float(s[-1]))

    def window(self, speed, direction, lookahead, max_ahead=math.inf):
        a = np.array(self.samples)
        t, x, y = a[:, 0], a[:, 1], a[:, 2]
        d = np.hypot(np.diff(x), np.diff(y))
        s = np.concatenate(([0.0], np.cumsum(d)))
        step, sl = self.step, s[-1]
        ks = np.arange(max(0, math.ceil((sl - HISTORY_M) / step)), math.floor(sl / step) + 1)
        at = ks * step
        # A segment runs from the sample before a moving sample (the end of any rest) to it.
        moving = np.flatnonzero(d > 0) + 1
        j = np.searchsorted(s[moving], at, side="left")
        j = np.minimum(j, max(moving.size - 1, 0))
        tk, xk, yk = np.empty(ks.size), np.empty(ks.size), np.empty(ks.size)
        for n, (k, jj) in enumerate(zip(ks, j)):
            if k == 0:
                tk[n], xk[n], yk[n] = t[0], x[0], y[0]
                continue
            e = moving[jj]
            b = e - 1
            for src, dst in ((t, tk), (x, xk), (y, yk)):
                dst[n] = np.interp(at[n], [s[b], s[e]], [src[b], src[e]])
        if direction is not None and speed > 0:
            kp = np.arange(math.floor(sl / step) + 1, math.floor((sl + min(speed * lookahead, max_ahead)) / step) + 1)
            off = kp * step - sl
            xp = x[-1] + math.cos(direction) * off
            yp = y[-1] - math.sin(direction) * off
            tp = t[-1] + off / speed
        else:
            xp = yp = tp = np.zeros(0)
        h, ids, fl = self.surface.regions(np.concatenate((xk, xp)), np.concatenate((yk, yp)))
        return Window(h, ids, fl, int(ks[0]) if ks.size else 0, ks.size, np.concatenate((tk, tp)), step)


def _stroke(path_cls, surface):
    stroke = SurfaceStroke(surface)
    stroke._path = path_cls(surface)
    return stroke


def _batches(samples, seed):
    """Batches of one to nine samples, as a page coalesces them."""
    rng = np.random.default_rng(seed)
    i, out = 0, []
    while i < len(samples):
        n = int(rng.integers(1, 10))
        out.append(samples[i : i + n])
        i += n
    return out


def _min_jerk_with_stops_reversal_curve_jump(y0):
    rate = 240.0
    t, x, y, t0 = [], [], [], 0.0
    legs = [(3e-3, 30e-3, 0.6, 0.15), (30e-3, 12e-3, 0.5, 0.2), (12e-3, 36e-3, 0.7, 0.05)]
    for a, b, dur, hold in legs:
        tt = np.arange(0.0, dur, 1 / rate)
        tau = tt / dur
        xs = a + (b - a) * (10 * tau**3 - 15 * tau**4 + 6 * tau**5)
        t += list(t0 + tt)
        x += list(xs)
        y += list(y0 + 1.5e-3 * np.sin(xs / 3e-3))  # a wavy line: both coordinates move
        t0 += dur
        th = np.arange(0.0, hold, 1 / rate)
        t += list(t0 + th)
        x += [b] * th.size
        y += [y[-1]] * th.size
        t0 += hold
    # A jump longer than the history (a lost stretch of samples), then on.
    t += list(t0 + np.arange(1, 60) / rate)
    x += list(5e-3 + 0.03 * np.arange(1, 60) / rate)
    y += [y0 + 2e-3] * 59
    return [PenSample(a, b, c) for a, b, c in zip(t, x, y)]


def _compare(surface, samples, seed):
    tracker = StrokeTracker()
    fast, ref = _stroke(PathGrid, surface), _stroke(ScratchPath, surface)
    total = 0
    for batch in _batches(samples, seed):
        st = tracker.extend(batch)
        if st is None:
            continue
        a = fast.update(batch, st.speed_m_s, st.direction_rad, st.pressure)
        b = ref.update(batch, st.speed_m_s, st.direction_rad, st.pressure)
        assert len(a) == len(b), (batch[-1].t_s, a, b)
        for ea, eb in zip(a, b):
            assert ea.t_s == pytest.approx(eb.t_s, abs=1e-9)
            assert ea.strength == pytest.approx(eb.strength, abs=1e-9)
            assert ea.clamped == eb.clamped
        assert fast.newly_fired == ref.newly_fired
        # The profile itself, point for point (asked again: nothing new is added).
        args = (st.speed_m_s, st.direction_rad, fast.lookahead_s)
        wa, wb = fast._path.window(*args), ref._path.window(*args)
        assert (wa.k0, wa.kept, len(wa.h)) == (wb.k0, wb.kept, len(wb.h))
        assert np.allclose(wa.h, wb.h, rtol=0, atol=1e-12, equal_nan=True) and (wa.ids == wb.ids).all()
        assert all(wa.t_at(i) == pytest.approx(wb.t_at(i), abs=1e-12) for i in range(len(wa.h)))
        total += fast.newly_fired
    return total


def test_incremental_path_gives_the_same_events_as_from_scratch_batch_for_batch():
    f = grain_field(1.2e-3, (40e-3, 12e-3), seed=3)
    sm = surface_model(f.heights, pitch_m=f.pitch_m)
    samples = _min_jerk_with_stops_reversal_curve_jump(6e-3)
    # With a gap longer than a stroke's silence in the middle: the stroke restarts.
    gap = [PenSample(s.t_s + 0.3, s.x_m, s.y_m) for s in samples[300:]]
    assert _compare(sm, samples[:300] + gap, seed=1) >= 30


def test_incremental_path_matches_from_scratch_across_pictures():
    a = grain_field(1.0e-3, (20e-3, 12e-3), seed=4)
    b = grain_field(2.5e-3, (20e-3, 12e-3), seed=5)
    sa, sb = surface_model(a.heights, pitch_m=a.pitch_m), surface_model(b.heights, pitch_m=b.pitch_m)
    comp = CompositeSurface.of([sa, sb, sb, sa], cols=2)
    samples = _min_jerk_with_stops_reversal_curve_jump(11e-3)  # along the boundary between rows
    assert _compare(comp, samples, seed=2) >= 30


def test_a_long_jump_keeps_only_the_history_behind_the_pen():
    sm = surface_model(grain_field(1e-3, (80e-3, 10e-3), seed=6).heights, pitch_m=0.1e-3)
    grid = PathGrid(sm)
    grid.add(0.0, 1e-3, 5e-3)
    grid.add(0.004, 70e-3, 5e-3)  # 69 mm in one step
    w = grid.window(0.0, None, 0.025)
    assert w.kept == len(w.h) <= HISTORY_M / sm.step_m + 1
    assert w.s_at(len(w.h) - 1) <= 69e-3 < w.s_at(len(w.h) - 1) + sm.step_m


def test_the_bump_search_is_find_peaks_with_the_prominence_floor():
    """bumps_in calls find_peaks' own steps: the same indices and prominences as find_peaks with
    the floor as its prominence, plateaus and ties included, one region or several."""
    from scipy.signal import find_peaks

    from tactilize.surface.bumps import bumps_in

    rng = np.random.default_rng(4)
    for _ in range(500):
        n = int(rng.integers(3, 300))
        h = np.round(rng.normal(size=n), int(rng.integers(1, 3)))  # rounded: plateaus and equal peaks
        floor = float(rng.uniform(0.0, 1.0))
        idx, prom = bumps_in(h, np.zeros(n, dtype=np.intp), np.full(n, floor))
        want, props = find_peaks(h, prominence=floor)
        assert np.array_equal(idx, want) and np.array_equal(prom, props["prominences"])
        cut = int(rng.integers(1, n))
        ids = np.where(np.arange(n) < cut, 0, 1)
        idx, prom = bumps_in(h, ids, np.full(n, floor))
        parts = [(find_peaks(h[a:b], prominence=floor), a) for a, b in ((0, cut), (cut, n)) if b - a >= 3]
        assert np.array_equal(idx, np.concatenate([p + a for (p, _), a in parts] or [np.zeros(0, int)]))
        assert np.array_equal(prom, np.concatenate([q["prominences"] for (_, q), _ in parts] or [np.zeros(0)]))
