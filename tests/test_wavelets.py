"""Pulse events as acceleration wavelets (tactilize.synthesis.wavelets): the event stream's
sound peaks where the tip's acceleration does."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from tactilize.surface import stroke_events, surface_model
from tactilize.surface.events import PulseEvent
from tactilize.surface.fields import grain_field, grating_field
from tactilize.synthesis.acceleration import spectral_centroid_hz, spectral_peak_hz, spectrum
from tactilize.synthesis.wavelets import SPAN_SIGMAS, event_wavelets, render_wavelets, ricker, wavelet_rows

RATE = 48_000.0


def _line(speed_m_s, duration_s=1.0):
    t = np.arange(0.0, duration_s, 1 / 240)
    return t, 5e-3 + speed_m_s * t, np.full(t.size, 10e-3)


@pytest.mark.parametrize("speed_m_s", [0.04, 0.1, 0.2])
def test_wavelets_of_a_grating_peak_at_v_fs(speed_m_s):
    pitch = 0.26e-3
    surface = surface_model(grating_field(1000.0, 0.0, (0.3, 0.02), pitch), pitch_m=pitch)
    x = render_wavelets(event_wavelets(stroke_events(surface, *_line(speed_m_s))), 0.0, int(RATE), RATE)
    f, p = spectrum(x, RATE)
    assert spectral_peak_hz(f, p) == pytest.approx(speed_m_s * 1000.0, rel=0.03)


def test_wavelets_of_grains_fall_in_centroid_as_pitch_rises():
    c = []
    for pitch in (0.5e-3, 1e-3, 2e-3, 4e-3):
        field = grain_field(pitch, (0.2, 0.02), px_per_pitch=8, seed=1)
        surface = surface_model(field.heights, pitch_m=field.pitch_m)
        x = render_wavelets(event_wavelets(stroke_events(surface, *_line(0.1))), 0.0, int(RATE), RATE)
        c.append(spectral_centroid_hz(*spectrum(x, RATE)))
    assert all(b < 0.8 * a for a, b in zip(c, c[1:])), c


def test_widths_follow_the_nearest_interval_inside_the_band():
    ev = [PulseEvent(0.0, 1.0), PulseEvent(0.010, 0.5), PulseEvent(0.0102, 0.5), PulseEvent(1.0, 0.2)]
    w = event_wavelets(ev)
    # 10 ms to its neighbour: the wavelet peaks at 100 Hz
    assert 1 / (np.sqrt(2) * np.pi * w[0].sigma_s) == pytest.approx(100.0)
    # 0.2 ms apart would peak at 5 kHz: held at the band's top, 1 kHz; a lone one at its floor, 20 Hz
    assert 1 / (np.sqrt(2) * np.pi * w[1].sigma_s) == pytest.approx(1000.0)
    assert 1 / (np.sqrt(2) * np.pi * w[3].sigma_s) == pytest.approx(20.0)
    assert [x.amplitude for x in w] == [1.0, 0.5, 0.5, 0.2]
    rows = wavelet_rows(ev, 0.5)
    assert rows[0][0] == pytest.approx(-0.5) and rows[3][1:] == [0.2, w[3].sigma_s]


def test_the_wavelet_is_a_bump_s_acceleration_cut_smoothly():
    tau = np.linspace(-4, 4, 8001)
    w = ricker(tau)
    assert w[4000] == -1.0 and np.all(w[np.abs(tau) >= SPAN_SIGMAS] == 0.0)
    # the second derivative of exp(-tau^2 / 2), negated, up to the taper
    inner = np.abs(tau) <= SPAN_SIGMAS - 1
    np.testing.assert_allclose(w[inner], -(1 - tau[inner] ** 2) * np.exp(-tau[inner] ** 2 / 2))
    assert np.max(np.abs(np.diff(w))) < 0.01  # no step anywhere


@settings(max_examples=200, deadline=None)
@given(hs.lists(hs.tuples(hs.floats(0.0, 0.05), hs.floats(0.0, 1.0)), max_size=12), hs.floats(-1.0, 1.0))
def test_the_page_rows_are_event_wavelets_exactly(items, now_s):
    # wavelet_rows is event_wavelets' arithmetic written out for the page (ties and
    # repeated times included): every row must be the same floats.
    t, ev = 0.0, []
    for dt, s in items:
        t += dt
        ev.append(PulseEvent(t, s))
    ref = [[w.t_s - now_s, w.amplitude, w.sigma_s] for w in event_wavelets(ev)]
    assert wavelet_rows(ev, now_s) == ref
