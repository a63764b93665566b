"""Sparse pen samples: a 60 Hz touch screen, a loaded page.

A bump's prominence needs its far side, so with samples further apart than the
prediction reaches a bump is often first seen by the batch after its crossing.
It must still play (once, late by at most a batch), not be left out.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactilize.data import builtin_textures
from tactilize.pen.replay import replay_stroke
from tactilize.pen.samples import PenSample
from tactilize.surface import stroke_events, surface_model
from tactilize.surface.fields import bump_field, true_crossings
from tactilize.surface.stroke import LOOKAHEAD_S


def _samples(t, x, y):
    return [PenSample(float(a), float(b), float(c)) for a, b, c in zip(t, x, y)]


@pytest.mark.parametrize("rate_hz", [60.0, 33.0])
@pytest.mark.parametrize("v_mm_s", [20, 40, 80])
def test_every_bump_plays_once_when_batches_come_sparse(rate_hz, v_mm_s):
    radius = 0.6e-3
    rng = np.random.default_rng(int(rate_hz) + v_mm_s)
    cx = 4e-3 + np.cumsum(3.0 * radius + rng.exponential(1.5e-3, 60))
    cx = cx[cx < 76e-3]
    y0 = 10e-3
    f = bump_field(np.stack([cx, np.full(cx.size, y0)], 1), radius, (80e-3, 20e-3), 0.05e-3)
    sm = surface_model(f.heights, pitch_m=f.pitch_m)
    v = v_mm_s * 1e-3
    t = np.arange(0.0, 72e-3 / v, 1.0 / rate_hz)
    x, y = 3e-3 + v * t, np.full(t.size, y0)
    truth = true_crossings(t, x, y, f.centres_m, radius)
    fired = np.array([e.t_s for e in replay_stroke(sm, _samples(t, x, y), batch_s=1.0 / rate_hz)])
    # Judged away from the stroke's end: a bump there has no far side in any sample, and what
    # the last batch predicted beyond the end no later batch withdrew.
    end_s = t[-1] - 3 * radius / v
    late_s = min(LOOKAHEAD_S, 1.0 / rate_hz) + 0.002  # at most one batch late (capped at the look-ahead)
    judged = truth[truth <= end_s]
    assert judged.size >= 15
    for c in judged:  # each crossing gets exactly one pulse
        near = fired[(fired >= c - 0.003) & (fired <= c + late_s)]
        assert near.size == 1, (c, fired)
    for p in fired[fired <= end_s]:  # and no pulse is off a crossing
        assert np.any((truth >= p - late_s) & (truth <= p + 0.003)), (p, truth)

def test_a_real_texture_keeps_every_ridge_at_touch_screen_rates():
    corduroy = next(t for t in builtin_textures() if t.id.startswith("cord"))
    sm = surface_model(corduroy.image)
    v = 0.036
    for rate_hz in (240.0, 60.0, 33.0):
        t = np.arange(0.0, 0.9 * sm.width_m / v, 1.0 / rate_hz)
        x, y = 0.05 * sm.width_m + v * t, np.full(t.size, sm.height_m / 2)
        offline = stroke_events(sm, t, x, y)
        live = [e for e in replay_stroke(sm, _samples(t, x, y), batch_s=1.0 / rate_hz) if e.t_s <= t[-1]]
        assert len(offline) >= 14
        assert len(live) == len(offline), rate_hz
