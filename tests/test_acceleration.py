"""The tip's vertical acceleration (tactilize.synthesis.acceleration): the issue's spectra, the
speed law, and no tone at speed / pixel pitch."""

from __future__ import annotations

import numpy as np
import pytest

from tactilize.errors import SignalError
from tactilize.surface import surface_model
from tactilize.surface.fields import grain_field, grating_field
from tactilize.synthesis.acceleration import (
    FULL_SCALE_ACCELERATION,
    band_limited_acceleration,
    heights_along,
    spectral_centroid_hz,
    spectral_peak_hz,
    spectrum,
    tip_acceleration,
    to_full_scale,
)

PITCH_M = 0.26e-3  # a 96 DPI screen's pixel
RATE = 48_000.0


def straight(speed_m_s: float, duration_s: float = 1.0, x0_m: float = 5e-3, y_m: float = 10e-3, rate_hz: float = 240.0):
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    return t, x0_m + speed_m_s * t, np.full(t.size, y_m)


@pytest.fixture(scope="module")
def grating():
    return surface_model(grating_field(1000.0, 0.0, (0.3, 0.02), PITCH_M), pitch_m=PITCH_M)


@pytest.mark.parametrize("speed_m_s", [0.04, 0.1, 0.25])
def test_grating_peaks_at_speed_times_spatial_frequency(grating, speed_m_s):
    sig = tip_acceleration(grating, *straight(speed_m_s), sample_rate_hz=RATE)
    f, p = spectrum(sig)
    assert spectral_peak_hz(f, p) == pytest.approx(speed_m_s * 1000.0, rel=0.03)


def test_grating_at_an_angle_peaks_at_the_speed_along_its_wave_vector():
    surface = surface_model(grating_field(1000.0, np.radians(60.0), (0.3, 0.03), PITCH_M), pitch_m=PITCH_M)
    sig = tip_acceleration(surface, *straight(0.2, y_m=15e-3), sample_rate_hz=RATE)
    f, p = spectrum(sig)
    assert spectral_peak_hz(f, p) == pytest.approx(0.2 * 1000.0 * 0.5, rel=0.04)


def test_acceleration_scales_as_speed_squared(grating):
    """At a fixed spatial spectrum (one grating) and inside the band: v^2."""
    rms = []
    for v in (0.05, 0.1, 0.2):
        a = tip_acceleration(grating, *straight(v), sample_rate_hz=RATE).samples
        rms.append(float(np.sqrt(np.mean(a[4800:-4800] ** 2))))
    assert rms[1] / rms[0] == pytest.approx(4.0, rel=0.03)
    assert rms[2] / rms[1] == pytest.approx(4.0, rel=0.03)
    # ...and is the grating's own v^2 (2 pi k)^2 A, after the tip's low-pass of the relief.
    tip = np.exp(-2 * np.pi**2 * (0.125e-3 * 1000.0) ** 2)
    assert rms[1] == pytest.approx(0.5 * tip * (2 * np.pi * 100.0) ** 2 / np.sqrt(2), rel=0.05)


def test_the_band_cuts_what_the_voice_coil_cannot_play(grating):
    """At 3 m/s the grating plays at 3 kHz, above the band: a fraction of a per cent of its
    physical acceleration is left (also runs the oversampled path: 12.5 um per sample)."""
    v = 3.0
    a = tip_acceleration(grating, *straight(v, duration_s=0.08), sample_rate_hz=RATE).samples
    tip = np.exp(-2 * np.pi**2 * (0.125e-3 * 1000.0) ** 2)
    physical_rms = 0.5 * tip * (2 * np.pi * v * 1000.0) ** 2 / np.sqrt(2)
    assert np.sqrt(np.mean(a[1000:-1000] ** 2)) < 0.01 * physical_rms


def test_grain_centroid_falls_as_pitch_rises():
    centroids = []
    for pitch in (0.5e-3, 1e-3, 2e-3, 4e-3):
        field = grain_field(pitch, (0.2, 0.02), px_per_pitch=8, seed=1)
        surface = surface_model(field.heights, pitch_m=field.pitch_m)
        f, p = spectrum(tip_acceleration(surface, *straight(0.1), sample_rate_hz=RATE))
        centroids.append(spectral_centroid_hz(f, p))
    assert all(b < 0.8 * a for a, b in zip(centroids, centroids[1:])), centroids


def _ramp(width_m: float = 0.1) -> np.ndarray:
    """A smooth curved ramp across the picture: (x / W)^2, no relief finer than the picture."""
    cols = int(round(width_m / PITCH_M))
    x = (np.arange(cols) + 0.5) * PITCH_M
    return np.tile(((x / width_m) ** 2).astype(np.float32), (40, 1))


def _tone_ratio(acc: np.ndarray, tone_hz: float) -> float:
    """Power within 5 Hz of ``tone_hz`` over the power of the whole band."""
    f, p = spectrum(acc, RATE)
    near = (f > tone_hz - 5) & (f < tone_hz + 5)
    band = (f >= 20) & (f <= 1000)
    return float(p[near].sum() / p[band].sum())


def _tone_power(acc: np.ndarray, tone_hz: float) -> float:
    f, p = spectrum(acc, RATE)
    return float(p[(f > tone_hz - 5) & (f < tone_hz + 5)].sum())


def test_no_tone_at_speed_over_pixel_pitch_on_a_smooth_ramp():
    """Band-limited interpolation adds nothing at v / pixel pitch; a nearest-pixel or
    bilinear lookup through the same filters does (so the test can fail)."""
    surface = surface_model(_ramp(), pitch_m=PITCH_M)
    v = 0.1
    tone = v / PITCH_M  # 385 Hz: inside the band
    t, x, y = straight(v, duration_s=0.8)
    sig = tip_acceleration(surface, t, x, y, sample_rate_hz=RATE)
    # The same path, the same band-pass and derivative, naive lookups of the height.
    tt = np.arange(sig.samples.size) / RATE
    xx, yy = np.interp(tt, t, x), np.interp(tt, t, y)
    cols = np.clip((xx / PITCH_M).astype(int), 0, surface.shape[1] - 1)
    rows = np.clip((yy / PITCH_M).astype(int), 0, surface.shape[0] - 1)
    nearest = band_limited_acceleration(surface.height[rows, cols].astype(np.float64), RATE)
    bilinear = band_limited_acceleration(surface.sample(xx, yy).astype(np.float64), RATE)
    assert _tone_ratio(nearest[4800:-4800], tone) > 0.1
    assert _tone_ratio(bilinear[4800:-4800], tone) > 0.1
    # Ours: nothing at the pixel rate (its power there is a millionth of the bilinear one's).
    assert _tone_power(sig.samples[4800:-4800], tone) < 1e-6 * _tone_power(bilinear[4800:-4800], tone)


def test_pressure_scales_the_signal(grating):
    t, x, y = straight(0.1)
    full = tip_acceleration(grating, t, x, y, sample_rate_hz=RATE).samples
    half = tip_acceleration(grating, t, x, y, 0.25, sample_rate_hz=RATE).samples
    ramp = tip_acceleration(grating, t, x, y, list(np.linspace(0.0, 0.5, t.size)), sample_rate_hz=RATE).samples
    np.testing.assert_allclose(half, 0.5 * full, atol=1e-9 * np.abs(full).max())
    # Rising pressure: silent at the start, full at the end.
    assert np.abs(ramp[:2000]).max() < 0.05 * np.abs(full).max()
    assert np.abs(ramp[-6000:-1000]).max() == pytest.approx(np.abs(full[-6000:-1000]).max(), rel=0.05)


def test_a_resting_pen_is_silent(grating):
    t = np.arange(0.0, 0.5, 1 / 240)
    sig = tip_acceleration(grating, t, np.full(t.size, 0.01), np.full(t.size, 0.01), sample_rate_hz=RATE)
    assert np.abs(sig.samples).max() < 1e-6 * FULL_SCALE_ACCELERATION


def test_a_polyline_path_adds_no_tone_at_the_pen_rate():
    """Speed changing at every sample (a polyline's corners) would put a comb at the pen's
    240 Hz into the a h' term; the spline through the samples does not."""
    tilt = np.tile(np.linspace(0.0, 2.5, int(0.025 / PITCH_M), dtype=np.float32), (40, 1))  # a plane, 100 /m
    surface = surface_model(tilt, pitch_m=PITCH_M)
    t = np.arange(0.0, 0.5, 1 / 240)
    x = 12e-3 + 5e-3 * np.sin(2 * np.pi * 4.0 * t)  # a hand going back and forth
    y = np.full(t.size, 5e-3)
    sig = tip_acceleration(surface, t, x, y, sample_rate_hz=RATE)
    # Linear interpolation of the same samples, through the same chain:
    tt = np.arange(sig.samples.size) / RATE
    poly = band_limited_acceleration(surface.sample(np.interp(tt, t, x), np.full(tt.size, 5e-3)).astype(float), RATE)
    assert _tone_ratio(poly[4800:-4800], 240.0) > 0.1
    ours = _tone_power(sig.samples[4800:-4800], 240.0)
    assert ours < 0.05 * _tone_power(poly[4800:-4800], 240.0)
    # What is left there is not the path's: the hand's true path gives the same.
    true_x = 12e-3 + 5e-3 * np.sin(2 * np.pi * 4.0 * tt)
    exact = band_limited_acceleration(heights_along(surface, true_x, np.full(tt.size, 5e-3)), RATE)
    assert ours == pytest.approx(_tone_power(exact[4800:-4800], 240.0), rel=0.05)


def test_full_scale_clips_and_counts(grating):
    sig = tip_acceleration(grating, *straight(0.25), sample_rate_hz=RATE)
    x, clipped = to_full_scale(sig)
    assert np.abs(x).max() <= 1.0
    assert clipped == 0
    loud, clipped = to_full_scale(sig, gain=100.0)
    assert clipped > 0 and np.abs(loud).max() == 1.0


def test_bad_strokes_raise_signal_error(grating):
    with pytest.raises(SignalError):
        tip_acceleration(grating, [0.0], [0.0], [0.0])
    with pytest.raises(SignalError):
        tip_acceleration(grating, [0.0, 0.0], [0.0, 1e-3], [0.0, 0.0])
    with pytest.raises(SignalError):
        tip_acceleration(grating, [0.0, 0.1], [0.0, np.nan], [0.0, 0.0])
    with pytest.raises(SignalError):
        tip_acceleration(grating, *straight(0.1), sample_rate_hz=1000.0)


def test_a_long_stroke_is_computed_in_blocks_that_join_seamlessly(grating, monkeypatch):
    from tactilize.synthesis import acceleration

    t, x, y = straight(0.1, duration_s=2.0)
    x = 5e-3 + 0.1 * t + 3e-3 * np.sin(2 * np.pi * 1.5 * t)  # speed changing too
    whole = tip_acceleration(grating, t, x, y, sample_rate_hz=RATE).samples
    monkeypatch.setattr(acceleration, "_CHUNK", 10_007)
    blocks = tip_acceleration(grating, t, x, y, sample_rate_hz=RATE).samples
    assert blocks.shape == whole.shape
    np.testing.assert_allclose(blocks, whole, atol=1e-6 * np.abs(whole).max())
