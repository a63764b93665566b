"""The stroke's fired and pending events as arrays (tactilize.surface.stroke, ._stroke_kernels).

The stroke keeps what it handed out in a ring of arrays; the equivalent Drive's window
statistics are one compiled pass over it.  They must be what the readable
``equivalent.window_statistics`` gives on the stroke's own ``recent`` events, to the
bit, through strokes with stops, reversals, held-up batches and rings that wrap; and
``recent`` must hold every event fired in the window and those scheduled, whatever the
speed (before, fired events more than the path's history behind were let go, which
shortened the 150 ms window to 4 mm of path above 27 mm/s).
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tactilize.pen.samples import PenSample
from tactilize.surface import SurfaceStroke, surface_model
from tactilize.surface import _stroke_kernels
from tactilize.surface.equivalent import WINDOW_S, equivalent_drive, window_statistics
from tactilize.surface.events import PulseEvent
from tactilize.surface.fields import grain_field, grating_field
from tactilize.surface.stroke import _CLAMPED, FIRED_KEPT

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])

_FIELD = grain_field(1.0e-3, (60e-3, 12e-3), seed=11)
_SURFACE = surface_model(_FIELD.heights, pitch_m=_FIELD.pitch_m)


@st.composite
def strokes(draw):
    """Batches of a stroke: speed changes, stops, a reversal, held-up batches."""
    n = draw(st.integers(20, 160))
    speeds = draw(st.lists(st.sampled_from([0.0, 0.01, 0.04, 0.08, 0.16, -0.04]), min_size=4, max_size=4))
    gaps = draw(st.lists(st.sampled_from([0.004, 0.004, 0.008, 0.016, 0.03]), min_size=n, max_size=n))
    held = draw(st.lists(st.sampled_from([0.0, 0.0, 0.0, 0.002, 0.01]), min_size=n, max_size=n))
    window = draw(st.sampled_from([WINDOW_S, 0.05, 0.5]))
    return speeds, gaps, held, window


def _check_stroke(speeds, gaps, held, window) -> int:
    """Drive a stroke; at every batch the compiled statistics must be the readable ones.
    Returns how many batches had events in their window."""
    stroke = SurfaceStroke(_SURFACE)
    t, x = 0.0, 5e-3
    checked = 0
    for k, (gap, late) in enumerate(zip(gaps, held)):
        v = speeds[k * len(speeds) // len(gaps)]
        t += gap
        x = min(55e-3, max(1e-3, x + v * gap))
        stroke.update([PenSample(t, x, 6e-3)], abs(v), (0.0 if v > 0 else math.pi) if v else None,
                      played_until_s=t + late if late else None)
        got = stroke.window_statistics(window)
        want = window_statistics(stroke.recent(window), stroke.now_s, window)
        assert got == want
        checked += got[0] > 0
    return checked


@SETTINGS
@given(strokes())
def test_window_statistics_are_those_of_the_recent_events_to_the_bit(case):
    _check_stroke(*case)


def test_a_stroke_with_a_stop_and_a_reversal_has_events_in_its_windows():
    """The comparison above is not vacuous: a plain stroke's windows hold events."""
    gaps = [0.004] * 200 + [0.016, 0.03] * 20
    held = [0.0, 0.002, 0.0, 0.01] * 60
    assert _check_stroke([0.04, 0.0, -0.04, 0.16], gaps, held, WINDOW_S) > 150


@SETTINGS
@given(st.integers(0, 700), st.integers(0, 9), st.floats(0.0, 3.0), st.sampled_from([0.05, 0.15, 10.0]),
       st.integers(0, 2**32 - 1))
def test_window_stats_over_a_ring_that_wrapped(nfired, npend, since, window_s, seed):
    """The compiled pass against the readable one on a ring of any fill, the oldest overwritten."""
    rng = np.random.default_rng(seed)
    ring = np.zeros((4, FIRED_KEPT))
    times = np.sort(rng.uniform(0.0, 3.0, nfired)) if rng.random() < 0.8 else rng.uniform(0.0, 3.0, nfired)
    fired = []
    for j, tj in enumerate(times):
        ev = PulseEvent(float(tj), float(rng.random()), _CLAMPED[int(rng.integers(0, 16))])
        c = j % FIRED_KEPT
        ring[:, c] = (ev.t_s, ev.strength, _CLAMPED.index(ev.clamped), 0.0)
        fired.append(ev)
    pend = np.zeros((4, 10))
    pending = []
    for k in range(npend):
        ev = PulseEvent(3.0 + 0.004 * k, float(rng.random()), _CLAMPED[int(rng.integers(0, 16))])
        pend[:3, k] = (ev.t_s, ev.strength, _CLAMPED.index(ev.clamped))
        pending.append(ev)
    out = np.zeros(5)
    n = _stroke_kernels.window_stats(ring, nfired, pend, npend, since, window_s, out)
    kept = fired[max(0, nfired - FIRED_KEPT):]
    want = window_statistics(kept + pending, since + window_s, window_s)
    assert n == want[0] == int(out[0])
    assert out[1:4].tolist() == list(want[1:4])
    assert tuple(sorted({name for f in [int(out[4])] for name in _CLAMPED[f]})) == want[4]


def _grating_stroke(speed_m_s: float, seconds: float) -> SurfaceStroke:
    """A straight stroke across ridges 2 mm apart, the output keeping up (everything handed out plays)."""
    g = grating_field(500.0, 0.0, (200e-3, 10e-3), 0.1e-3)
    stroke = SurfaceStroke(surface_model(g, pitch_m=0.1e-3))
    for k in range(int(seconds / 0.004)):
        t = 0.004 * k
        stroke.update([PenSample(t, 2e-3 + speed_m_s * t, 5e-3)], speed_m_s, 0.0)
    return stroke


def test_the_window_is_150_ms_of_events_at_any_speed():
    for speed in (0.02, 0.08, 0.16):
        stroke = _grating_stroke(speed, 1.0)
        rate = speed / 2e-3
        fired_in_window = [e for e in stroke.recent(WINDOW_S) if e.t_s <= stroke.now_s]
        # 150 ms of ridges at 10, 40, 80 a second: 1-2, 6, 12 (before: 4 mm of path, 2 at 80 and 160 mm/s).
        assert abs(len(fired_in_window) - rate * WINDOW_S) <= 1.5, (speed, len(fired_in_window))
        d = equivalent_drive(stroke.recent(WINDOW_S), stroke.now_s)
        assert abs(d.pulse_frequency_hz - rate) <= 0.05 * rate


def test_recent_is_every_event_fired_since_and_those_scheduled():
    stroke = SurfaceStroke(_SURFACE)
    handed: list[list[PulseEvent]] = []
    for k in range(300):  # 1.2 s at 40 mm/s, about 48 grains
        t = 0.004 * k
        handed.append(stroke.update([PenSample(t, 2e-3 + 0.04 * t, 6e-3)], 0.04, 0.0))
    now = stroke.now_s
    # An event handed out by batch k fired when the next batch came at or after its time.
    fired = [e for k, evs in enumerate(handed[:-1]) for e in evs if e.t_s <= 0.004 * (k + 1)]
    want = [e for e in fired if e.t_s >= now - WINDOW_S] + handed[-1]
    assert stroke.recent(WINDOW_S) == want
    assert len(want) >= 4


@SETTINGS
@given(st.integers(0, 600), st.lists(st.floats(0.0, 2.0), max_size=12), st.floats(0.0, 2.0),
       st.one_of(st.just(math.nan), st.floats(0.0, 2.0)))
def test_fire_due_moves_the_due_events_in_order_and_keeps_the_latest_time(nfired, times, played, last_t):
    ring = np.zeros((4, FIRED_KEPT))
    ring[0] = -1.0
    pend = np.zeros((4, len(times) + 1))
    for k, t in enumerate(times):
        pend[:, k] = (t, 0.5 + k, k % 16, 10.0 + k)
    got_n, got_last = _stroke_kernels.fire_due(pend, len(times), played, ring, nfired, last_t)
    due = [k for k, t in enumerate(times) if t <= played]
    assert got_n == nfired + len(due)
    want_last = max([t for t in times if t <= played] + ([] if math.isnan(last_t) else [last_t]), default=math.nan)
    assert got_last == want_last or (math.isnan(got_last) and math.isnan(want_last))
    for j, k in enumerate(due):
        assert ring[:, (nfired + j) % FIRED_KEPT].tolist() == pend[:, k].tolist()
