"""The stroke's compiled pass (``_stroke_kernels.place_crossings``) against its readable rule.

A batch's bumps become pulse events by the stroke's rule (too late, or already
played within half a tip radius of arc: left out; the rest at the newest sample's
time at the earliest, in time order), then ``events.strengths`` and
``events.place_events``.  The reference below is that rule in plain Python, built on
the library's own ``strengths`` and ``place_events``; the compiled pass must give the
same events (times and strengths to the bit, the same ``clamped`` names in the same
order) and the same arcs, on crossings drawn to hit every rule: merges, clusters,
rate-only stretches, reversals, late and played bumps, pressure.
"""

from __future__ import annotations

import math
from bisect import bisect_left

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from tactilize.surface import _stroke_kernels
from tactilize.surface import stroke as stroke_mod
from tactilize.surface.events import (CLUSTER_INTERVAL_S, FULL_PROMINENCE, MIN_INTERVAL_S, RATE_ONLY_HZ,
                                      pressure_scale, place_events, strengths)

SETTINGS = settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def reference(idx, prom, tc, floors, k0, step, fired, same, late, now, pressure, previous):
    """The rule as SurfaceStroke.update applied it in Python: [(PulseEvent, arc [m])]."""
    fired_s = sorted(fired)
    nf = len(fired_s)
    times, arcs, prominence, floor = [], [], [], []
    for i, p, ti in zip(idx, prom, tc):
        if ti <= late:
            continue
        si = (k0 + i) * step
        k = bisect_left(fired_s, si)
        if (k < nf and fired_s[k] - si < same) or (k > 0 and si - fired_s[k - 1] < same):
            continue
        times.append(ti if ti > now else now)
        arcs.append(si)
        prominence.append(p)
        floor.append(floors[i])
    if not times:
        return []
    s = strengths(prominence, floor, pressure)
    order = sorted(range(len(times)), key=times.__getitem__)
    times = [times[i] for i in order]
    arcs = [arcs[i] for i in order]
    s = [s[i] for i in order]
    out, j = [], 0
    for ev in place_events(times, s, previous_t_s=previous):
        while j < len(times) and times[j] < ev.t_s:
            j += 1
        if ev.t_s <= now:
            ev = ev._replace(t_s=now, clamped=ev.clamped + ("late",))
        out.append((ev, arcs[min(j, len(arcs) - 1)]))
    return out


def compiled(idx, prom, tc, floors, k0, step, fired, same, late, now, pressure, previous):
    n = len(idx)
    out = np.zeros((4, n + 1))
    ring = np.zeros((4, max(len(fired), 1)))
    ring[3, : len(fired)] = fired
    scale = pressure_scale(pressure)
    # Floors sit in a longer buffer, at an offset, as in the path's grid.
    buf = np.concatenate((np.full(3, -1.0), np.asarray(floors, dtype=np.float64)))
    k = _stroke_kernels.place_crossings(
        np.asarray(idx, dtype=np.intp), np.asarray(prom, dtype=np.float64), np.asarray(tc, dtype=np.float64), buf,
        3, k0, step, ring, len(fired), same, late, now, scale, math.nan if previous is None else previous,
        FULL_PROMINENCE, RATE_ONLY_HZ, MIN_INTERVAL_S, CLUSTER_INTERVAL_S, out)
    return [(stroke_mod.PulseEvent(out[0, i], out[1, i], stroke_mod._CLAMPED[int(out[2, i])]), out[3, i])
            for i in range(k)]


def _same(got, want):
    assert len(got) == len(want)
    for (g, ga), (w, wa) in zip(got, want):
        assert g.t_s == w.t_s and g.clamped == w.clamped and ga == wa
        assert g.strength == w.strength or math.isclose(g.strength, w.strength, rel_tol=0, abs_tol=0)


# Steps between crossings around every threshold: merged (< 1/300 s), cluster (< 1/150 s),
# rate-only (local rate > 150 /s), equal times, and a step back (a reversal's edge).
_STEP = st.one_of(st.sampled_from([0.0, 1e-3, 3.3e-3, 1 / 300, 3.4e-3, 6.6e-3, 1 / 150, 7e-3, 0.02, -2e-3]),
                  st.floats(-5e-3, 0.03))
_PROM = st.one_of(st.sampled_from([1e-13, 0.01, 0.02, 0.5, 0.7, 2.0]), st.floats(1e-6, 1.0))


@st.composite
def batches(draw):
    n = draw(st.integers(0, 12))
    idx = sorted(draw(st.sets(st.integers(0, 120), min_size=n, max_size=n)))
    steps = draw(st.lists(_STEP, min_size=n, max_size=n))
    tc = list(np.cumsum([1.0] + steps)[1:]) if n else []
    prom = draw(st.lists(_PROM, min_size=n, max_size=n))
    floors = [draw(st.sampled_from([0.005, 0.02, 0.1, 0.5, 0.9])) for _ in range(121)]
    k0 = draw(st.integers(0, 10_000))
    step = draw(st.sampled_from([62.5e-6, 0.1e-3, 1 / 3 * 1e-3]))
    same = 0.5 * draw(st.sampled_from([0.25e-3, 0.5e-3, 1e-3]))
    # Played arcs on, beside and between the crossings' arcs.
    fired = [(k0 + i) * step + draw(st.sampled_from([0.0, 0.3, -0.49, 0.5, -0.51, 2.0])) * 2 * same
             for i in draw(st.lists(st.sampled_from(idx), max_size=4))] if idx else []
    fired += draw(st.lists(st.floats(k0 * step - 1e-3, (k0 + 130) * step), max_size=3))
    now = 1.0 + draw(st.floats(-0.01, 0.06))
    late = now - draw(st.sampled_from([0.005, 0.025, 0.0, 0.5]))
    pressure = draw(st.one_of(st.none(), st.floats(0.0, 1.0), st.sampled_from([0.0, 0.5, 1.0])))
    previous = draw(st.one_of(st.none(), st.floats(0.95, 1.01), st.sampled_from([1.0, now])))
    return idx, prom, tc, floors, k0, step, fired, same, late, now, pressure, previous


@SETTINGS
@given(batches())
@example(([3, 4, 5, 6], [0.5, 0.5, 0.5, 0.5], [1.001, 1.002, 1.003, 1.004], [0.02] * 121, 0, 1e-4, [], 1e-4,
          0.0, 0.9, None, None))  # a rate-only run whose medians read values already replaced
@example(([3, 9], [0.5, 0.6], [1.010, 1.004], [0.02] * 121, 5, 1e-4, [], 1e-4, 0.0, 1.005, 0.7, 1.0))
def test_compiled_pass_places_what_the_readable_rule_places(batch):
    _same(compiled(*batch), reference(*batch))


def test_every_rule_is_exercised_by_the_examples():
    """The reference is not vacuous: merges, clusters, rate-only, late and played bumps occur."""
    rng = np.random.default_rng(5)
    seen: set[str] = set()
    dropped = 0
    for _ in range(300):
        n = int(rng.integers(2, 10))
        tc = list(1.0 + np.cumsum(rng.choice([1e-3, 4e-3, 0.02, -2e-3], n)))
        idx = sorted(rng.choice(100, n, replace=False).tolist())
        fired = [(i * 1e-4) for i in idx[:1]]
        got = compiled(idx, [0.3] * n, tc, [0.02] * 121, 0, 1e-4, fired, 5e-5, 1.0, 1.003, None, 0.999)
        _same(got, reference(idx, [0.3] * n, tc, [0.02] * 121, 0, 1e-4, fired, 5e-5, 1.0, 1.003, None, 0.999))
        dropped += n - len(got)
        for ev, _ in got:
            seen.update(ev.clamped)
    assert seen == {"rate_only", "cluster", "merged", "late"}
    assert dropped > 300
