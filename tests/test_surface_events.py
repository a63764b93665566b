"""The surface rendering: a height field through the tip, and one pulse per bump crossed.

Every field is generated in code with its bumps known (tactilize.surface.fields),
so each assertion compares pulses with the true crossings.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactilize.errors import ImageError
from tactilize.pen.samples import PenSample
from tactilize.surface import CompositeSurface, place_events, stroke_events, surface_model
from tactilize.surface.events import MAX_RATE_HZ, RATE_ONLY_HZ, event_statistics
from tactilize.surface.fields import (
    bump_field,
    bump_line_field,
    grain_field,
    grating_field,
    min_jerk_path,
    true_crossings,
)
from tactilize.pen.replay import replay_stroke
from tactilize.surface.path import HISTORY_M

FREQUENCY_JND = 0.2


def _line(v_m_s: float, x0: float, x1: float, y: float, rate_hz: float = 500.0):
    t = np.arange(0.0, (x1 - x0) / v_m_s, 1.0 / rate_hz)
    return t, x0 + v_m_s * t, np.full(t.size, y)


# ---------------------------------------------------------------- the model


def test_luminance_is_height_bright_high_and_tip_filters():
    img = np.zeros((64, 64), np.float32)
    img[32, 32] = 1.0  # one bright pixel: a spike the tip cannot enter
    sharp = surface_model(img, pitch_m=1e-4, tip_radius_m=1e-6)
    blunt = surface_model(img, pitch_m=1e-4, tip_radius_m=1e-3)
    assert sharp.sample(np.array([3.25e-3]), np.array([3.25e-3]))[0] == pytest.approx(1.0)
    # A 1 mm tip spreads the spike: it reads far lower but still highest at the spike.
    row = blunt.sample(np.linspace(2e-3, 4.5e-3, 51), np.full(51, 3.25e-3))
    assert row.max() < 0.2 and np.argmax(row) == 25


def test_real_scale_is_apart_from_display_size():
    f = grain_field(2e-3, (40e-3, 10e-3), seed=2)
    shown = surface_model(f.heights, pitch_m=f.pitch_m)
    # The same picture as a surface four times smaller than shown: the tip, in
    # surface metres, covers four times more of the picture.
    small = shown.at_scale(f.pitch_m / 4)
    assert small.width_m == shown.width_m and small.surface_per_display == pytest.approx(0.25)
    assert small.step_m > shown.step_m
    assert np.std(small.height) < np.std(shown.height)
    assert shown.at_display_pitch(2 * f.pitch_m).surface_pitch_m == (2 * f.pitch_m, 2 * f.pitch_m)
    assert small.at_display_pitch(2 * f.pitch_m).surface_pitch_m == small.surface_pitch_m


@pytest.mark.parametrize("bad", [np.zeros((3, 3, 3)), np.array([[np.nan, 0.0]])])
def test_bad_height_fields_raise_one_error(bad):
    with pytest.raises(ImageError):
        surface_model(bad, pitch_m=1e-4)
    with pytest.raises(ImageError):
        surface_model(np.zeros((4, 4)), pitch_m=1e-4, tip_radius_m=-1.0)


# ---------------------------------------------------------------- accuracy


@pytest.mark.parametrize("v_mm_s", [10, 20, 40, 80, 160])
def test_straight_strokes_match_true_crossings_both_ways(v_mm_s):
    radius = 0.6e-3
    f, y0 = bump_line_field(seed=v_mm_s, radius_m=radius)
    sm = surface_model(f.heights, pitch_m=f.pitch_m)
    v = v_mm_s / 1e3
    t, x, y = _line(v, 2e-3, 78e-3, y0)
    truth = true_crossings(t, x, y, f.centres_m, radius)
    pulses = np.array([e.t_s for e in stroke_events(sm, t, x, y)])
    tol = max(2e-3, 0.25 * radius / v)
    assert truth.size >= 20
    matched = [np.min(np.abs(truth - p)) <= tol for p in pulses]
    assert np.mean(matched) >= 0.95
    once = [np.sum(np.abs(pulses - c) <= tol) == 1 for c in truth]
    assert np.mean(once) >= 0.95


def test_grains_rate_follows_speed_over_pitch_and_falls_with_pitch():
    v = 0.040
    rates = []
    for pitch in (0.5e-3, 1e-3, 2e-3, 4e-3, 8e-3):
        length = 60 * pitch  # >= 50 bumps a stroke
        f = grain_field(pitch, (length + 2 * pitch, 10 * pitch), seed=11)
        sm = surface_model(f.heights, pitch_m=f.pitch_m)
        counts, duration = 0, 0.0
        for k in range(4):
            t, x, y = _line(v, pitch, pitch + length, (2.2 + 1.7 * k) * pitch)
            counts += len(stroke_events(sm, t, x, y))
            duration += t[-1]
        rate = counts / duration
        expected = v / pitch
        assert expected <= RATE_ONLY_HZ
        assert expected / 1.5 <= rate <= expected * 1.5, (pitch, rate, expected)
        rates.append(rate)
    assert all(a > b for a, b in zip(rates, rates[1:]))
    assert all(a >= b * (1 + FREQUENCY_JND) for a, b in zip(rates, rates[1:]))


@pytest.mark.parametrize("theta_deg", [0, 30, 60, 75])
def test_grating_at_an_angle_gives_v_fs_cos(theta_deg):
    f_s, v = 1000.0, 0.060  # 1 mm period: 60 /s along the wave vector
    th = math.radians(theta_deg)
    h = grating_field(f_s, th, (80e-3, 20e-3), 0.05e-3)
    sm = surface_model(h, pitch_m=0.05e-3)
    t, x, y = _line(v, 5e-3, 75e-3, 10e-3)
    ev = stroke_events(sm, t, x, y)
    expected = v * f_s * abs(math.cos(th))
    assert len(ev) / t[-1] == pytest.approx(expected, rel=0.1)


def test_min_jerk_strokes_with_stops_and_reversal_in_simulated_time():
    errors, spurious, total = [], 0, 0
    for seed in range(3):
        radius = 0.6e-3
        f, y0 = bump_line_field(seed=100 + seed, radius_m=radius)
        sm = surface_model(f.heights, pitch_m=f.pitch_m)
        points = [3e-3, 40e-3, 55e-3, 22e-3, 77e-3]
        t, x = min_jerk_path(points, [0.8, 0.35, 0.7, 1.0], [0.2, 0.15, 0.3, 0.1], rate_hz=500.0)
        samples = [PenSample(a, b, y0) for a, b in zip(t, x)]
        truth = true_crossings(t, x, np.full(t.size, y0), f.centres_m, radius)
        fired = replay_stroke(sm, samples, batch_s=0.004, transport_s=0.001)
        assert truth.size >= 20
        for k, e in enumerate(fired):
            err = np.min(np.abs(truth - e.t_s))
            if err > 0.010:
                spurious += k > 0  # the first bump from cold excepted
            else:
                errors.append(err)
        total += len(fired)
    assert np.percentile(errors, 95) <= 0.005
    assert spurious <= 0.02 * total


def test_bumps_merged_into_one_pulse_are_not_played_again_by_a_later_batch():
    """Pairs of bumps 2.5 ms apart at 0.2 m/s (closer than the wire's 1/300 s): each pair is one
    pulse, at its first bump, in real time as on the whole path.  A batch that finds the second
    bump again once the first has played must know it merged into that pulse (it used to fire it
    late, as a pulse of its own: 41 pulses for 23 pairs)."""
    v, y0 = 0.2, 5e-3
    firsts = np.arange(4e-3, 76e-3, 3e-3)
    f = bump_field(np.array([(a + d, y0) for a in firsts for d in (0.0, 0.5e-3)]), 0.2e-3, (80e-3, 10e-3), 25e-6)
    sm = surface_model(f.heights, pitch_m=f.pitch_m)
    t = np.arange(0.0, 0.36, 1 / 240)
    x = 1e-3 + v * t
    truth = true_crossings(t, x, np.full(t.size, y0), f.centres_m, f.radii_m)
    pairs = truth[::2]
    fired = [e.t_s for e in replay_stroke(sm, [PenSample(a, b, y0) for a, b in zip(t, x)], transport_s=0.0)]
    assert len(pairs) == 23 and len(fired) == len(pairs)
    assert np.max(np.abs(np.array(fired) - pairs)) < 1 / 240


# ---------------------------------------------------------------- the rules


def test_same_spot_feels_the_same_stroked_either_way():
    f = grain_field(1.5e-3, (40e-3, 10e-3), seed=5)
    sm = surface_model(f.heights, pitch_m=f.pitch_m)
    t, x, y = _line(0.05, 2e-3, 38e-3, 5e-3)
    there = stroke_events(sm, t, x, y)
    back = stroke_events(sm, t, x[::-1].copy(), y)
    assert len(there) == len(back) >= 10
    # Where each pulse is on the surface: the same places, the same strengths.
    pos_there = np.interp([e.t_s for e in there], t, x)
    pos_back = np.interp([e.t_s for e in back], t, x[::-1])
    assert np.allclose(np.sort(pos_there), np.sort(pos_back), atol=2 * sm.step_m)
    # Strengths bump by bump (in place order), away from where a stroke starts: there the pen has
    # no path behind it yet, a bump's prominence only the side ahead (the stroke that ends there
    # sees it from both sides, its path and its prediction; the two ends are left out alike).
    def inner(pos, events):
        return [e.strength for p, e in sorted(zip(pos, events)) if x[0] + HISTORY_M / 2 < p < x[-1] - HISTORY_M / 2]

    assert len(inner(pos_there, there)) >= 10
    assert inner(pos_there, there) == pytest.approx(inner(pos_back, back), abs=0.02)


def test_silent_while_the_pen_rests():
    f = grain_field(1e-3, (20e-3, 10e-3), seed=6)
    sm = surface_model(f.heights, pitch_m=f.pitch_m)
    t = np.arange(0.0, 1.0, 1 / 240)
    assert stroke_events(sm, t, np.full(t.size, 7.3e-3), np.full(t.size, 5e-3)) == []
    samples = [PenSample(a, 7.3e-3, 5e-3) for a in t]
    assert replay_stroke(sm, samples) == []


def test_pressure_scales_strength():
    f = grain_field(2e-3, (40e-3, 10e-3), seed=7)
    sm = surface_model(f.heights, pitch_m=f.pitch_m)
    t, x, y = _line(0.04, 2e-3, 38e-3, 5e-3)
    full = stroke_events(sm, t, x, y, pressure=1.0)
    light = stroke_events(sm, t, x, y, pressure=0.1)
    assert len(full) == len(light) > 5
    assert all(b.strength == pytest.approx(0.2 * a.strength) for a, b in zip(full, light))


def test_clusters_are_weaker_and_marked():
    ev = place_events([0.0, 0.1, 0.105, 0.2, 0.2005], [0.8] * 5)
    assert [e.t_s for e in ev] == [0.0, 0.1, 0.105, 0.2]
    assert ev[2].strength < 0.8 and "cluster" in ev[2].clamped
    assert "merged" in ev[3].clamped  # the crossing 0.5 ms after it folded in
    assert ev[0].clamped == () and ev[0].strength == 0.8


def test_above_150_per_second_only_rate_and_never_above_the_band():
    # A 0.2 mm grating at 160 mm/s asks for 800 pulses a second.
    h = grating_field(5000.0, 0.0, (40e-3, 5e-3), 0.02e-3)
    sm = surface_model(h, pitch_m=0.02e-3, tip_radius_m=0.05e-3)
    t, x, y = _line(0.16, 2e-3, 38e-3, 2.5e-3, rate_hz=1000.0)
    ev = stroke_events(sm, t, x, y)
    stats = event_statistics(ev)
    assert RATE_ONLY_HZ < stats.rate_hz <= MAX_RATE_HZ * 1.01
    assert all("rate_only" in e.clamped for e in ev[3:-3])
    assert min(np.diff([e.t_s for e in ev])) >= 1 / MAX_RATE_HZ - 1e-12


def test_a_stroke_into_the_next_picture_changes_rendering_within_5_ms():
    pitch = 0.1e-3
    # Ridges every mm, the first 0.5 mm from the picture's left edge.
    bumpy = np.roll(grating_field(1000.0, 0.0, (30e-3, 30e-3), pitch), 5, axis=1)
    flat = np.full_like(bumpy, 0.5)
    sm_b, sm_f = surface_model(bumpy, pitch_m=pitch), surface_model(flat, pitch_m=pitch)
    v = 0.08
    boundary = 30e-3
    for left, right in ((sm_b, sm_f), (sm_f, sm_b)):
        comp = CompositeSurface.of([left, right, sm_f, sm_f, sm_f, sm_f], cols=3)
        t, x, y = _line(v, 5e-3, 55e-3, 12e-3)
        samples = [PenSample(a, b, c) for a, b, c in zip(t, x, y)]
        fired = [e.t_s for e in replay_stroke(comp, samples)]
        t_cross = (boundary - 5e-3) / v
        if left is sm_b:
            assert max(fired) <= t_cross + 0.005
        else:
            first_ridge = t_cross + 0.5e-3 / v
            assert min(fired) == pytest.approx(first_ridge, abs=0.005)
            assert min(fired) >= t_cross
