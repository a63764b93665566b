"""features.py: the dominant spatial frequency, i_s, orientation and the extra descriptors."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tactilize as tz
from conftest import grating_array
from tactilize.features import NO_PEAK, analyse_stack


def _angle_error(a: float, b: float) -> float:
    """Smallest difference between two axial angles [deg] (mod 180)."""
    return abs((a - b + 90.0) % 180.0 - 90.0)


# Frequencies across the paper's range (Table 1/2: 265 .. 4217 per metre and beyond), at a
# dpi that keeps each at least 4 pixels per period (Nyquist is 2).
CASES = [
    (250.0, 300, (512, 512)),
    (443.0, 300, (384, 640)),
    (799.0, 300, (480, 360)),
    (1500.0, 600, (512, 700)),
    (2600.0, 600, (300, 500)),
    (4500.0, 600, (512, 512)),
]


@pytest.mark.parametrize("f, dpi, shape", CASES)
@pytest.mark.parametrize("angle", [0.0, 23.5, 61.0, 90.0, 128.0, 171.0])
def test_grating_frequency_within_1_percent_and_angle_within_2_degrees(f, dpi, shape, angle):
    arr = grating_array(shape, f, angle, dpi, contrast=0.8, noise=0.08, seed=int(f + angle))
    feat = tz.extract_features(tz.load_image(arr, dpi=dpi))
    assert feat.spatial_frequency_per_m == pytest.approx(f, rel=0.01)
    assert _angle_error(feat.orientation_deg, angle) < 2.0
    assert feat.has_peak
    assert feat.anisotropy > 0.5  # a grating under noise is still strongly oriented


def test_frequency_scales_exactly_with_dpi(tmp_path, make_grating):
    from PIL import Image

    arr = make_grating((256, 320), 800.0, 30.0, 300)
    path = tmp_path / "g.png"
    Image.fromarray((arr * 255).astype(np.uint8)).save(path)
    a = tz.extract_features(tz.load_image(path, dpi=300))
    b = tz.extract_features(tz.load_image(path, dpi=150))
    # The same pixels shown twice as large: half the cycles per metre, exactly.
    assert b.spatial_frequency_per_m / a.spatial_frequency_per_m == pytest.approx(0.5, rel=1e-12)
    assert b.orientation_deg == pytest.approx(a.orientation_deg, abs=1e-9)
    # ... and rescaling the measured features gives the same answer without a new FFT.
    assert a.at_dpi(150).spatial_frequency_per_m == pytest.approx(b.spatial_frequency_per_m, rel=1e-12)


def test_spectral_intensity_rises_with_contrast(make_grating):
    values = [
        tz.extract_features(tz.load_image(make_grating((256, 256), 800, 10, 300, contrast=c))).spectral_intensity
        for c in (0.02, 0.1, 0.3, 0.6, 1.0)
    ]
    assert all(0.0 < v <= 1.0 for v in values)
    assert values == sorted(values) and len(set(values)) == len(values)
    # docs/references.md, section 1 (reading of i_s): a strong grating reads about 0.9.
    assert values[-1] > 0.85


def test_spectral_intensity_matches_its_definition_on_an_exact_grating():
    # On-bin cosine in 8-bit levels: |F(k)| = 255 * A/2 * N, |F(0)| = 255 * mean * N (numpy's own DFT).
    n = 128
    x = np.arange(n)
    arr = np.tile(0.5 + 0.4 * np.cos(2 * np.pi * 8 * x / n), (n, 1)).astype(np.float32)
    dft = np.abs(np.fft.fft2(arr * 255.0))
    expected = math.log1p(dft[0, 8]) / math.log1p(dft[0, 0])
    feat = tz.extract_features(tz.load_image(arr))
    assert feat.spectral_intensity == pytest.approx(expected, rel=1e-4)
    assert feat.peak_amplitude == pytest.approx(0.4, rel=1e-3)
    assert feat.modulation_depth == pytest.approx(0.8, rel=1e-3)


def test_modulation_depth_is_size_independent_but_intensity_is_not(make_grating):
    small = tz.extract_features(tz.load_image(make_grating((128, 128), 800, 0, 300, contrast=0.5)))
    large = tz.extract_features(tz.load_image(make_grating((1024, 1024), 800, 0, 300, contrast=0.5)))
    assert small.modulation_depth == pytest.approx(0.5, rel=0.02)
    assert large.modulation_depth == pytest.approx(0.5, rel=0.02)
    assert large.spectral_intensity > small.spectral_intensity


def test_constant_image_has_the_documented_no_peak_values():
    feat = tz.extract_features(tz.load_image(np.full((64, 96), 0.7, np.float32)))
    assert feat.spatial_frequency_per_m == 0.0
    assert feat.spectral_intensity == 0.0
    assert feat.orientation_deg == 0.0
    assert feat.anisotropy == 0.0
    assert feat.periodicity == 0.0 and feat.contrast == 0.0 and feat.roughness_per_m == 0.0
    assert not feat.has_peak
    assert feat.wavelength_m == math.inf
    assert feat.mean_level == pytest.approx(0.7)
    assert NO_PEAK.spatial_frequency_per_m == 0.0
    values = [v for v in feat.to_dict().values() if isinstance(v, float)]
    assert values and all(math.isfinite(v) for v in values if v != math.inf)


def test_tiny_images_are_defined():
    feat = tz.extract_features(tz.load_image(np.array([[0.0, 1.0], [1.0, 0.0]], np.float32)))
    assert feat.spatial_frequency_per_m == 0.0 and not math.isnan(feat.spectral_intensity)


def test_white_noise_is_defined_and_not_periodic():
    rng = np.random.default_rng(3)
    feat = tz.extract_features(tz.load_image(rng.random((256, 256)).astype(np.float32)), tamura=True)
    d = feat.to_dict()
    assert all(not (isinstance(v, float) and math.isnan(v)) for v in d.values())
    assert feat.periodicity < 0.01
    assert feat.anisotropy < 0.1
    # uniform noise on [0, 1]: standard deviation 1/sqrt(12)
    assert feat.contrast == pytest.approx(1 / math.sqrt(12), rel=0.05)
    assert feat.directionality < 0.3


def test_a_grating_is_periodic_and_noise_reduces_it(make_grating):
    clean = tz.extract_features(tz.load_image(make_grating((256, 256), 800, 40, 300)))
    noisy = tz.extract_features(tz.load_image(make_grating((256, 256), 800, 40, 300, noise=0.3)))
    assert clean.periodicity > 0.9
    assert noisy.periodicity < clean.periodicity


def test_roughness_of_a_grating_matches_the_analytic_gradient(make_grating):
    # I = 0.5 + 0.5 c cos(2 pi f x): RMS of dI/dx = 0.5 c 2 pi f / sqrt(2).
    f, c = 800.0, 0.6
    feat = tz.extract_features(tz.load_image(make_grating((512, 512), f, 0, 300, contrast=c, quantise=False), dpi=300))
    expected = 0.5 * c * 2 * math.pi * f / math.sqrt(2)
    assert feat.roughness_per_m == pytest.approx(expected, rel=0.03)
    assert feat.contrast == pytest.approx(0.5 * c / math.sqrt(2), rel=0.03)


def test_anisotropic_pitch_changes_frequency_and_angle_consistently(make_grating):
    arr = make_grating((256, 256), 800, 45, 300, quantise=False)
    feat = tz.extract_features(tz.load_image(arr, dpi=300))
    px = feat.pitch_m[0]
    stretched = feat.at_pitch((2 * px, px))  # pixels twice as wide: x frequency halves
    kx, ky = feat.wave_vector_per_m
    assert stretched.wave_vector_per_m == pytest.approx((kx / 2, ky))
    assert stretched.orientation_deg == pytest.approx(math.degrees(math.atan2(ky, kx / 2)), abs=1e-9)


def test_radial_profile_peaks_at_the_grating_frequency(make_grating):
    f = 1200.0
    freq, power = tz.radial_profile(tz.load_image(make_grating((256, 256), f, 20, 300), dpi=300))
    assert freq.shape == power.shape and np.all(np.diff(freq) > 0)
    assert freq[int(np.argmax(power))] == pytest.approx(f, rel=0.03)


def test_tamura_coarseness_grows_with_element_size():
    def checker(cell: int) -> np.ndarray:
        yy, xx = np.mgrid[0:256, 0:256]
        return (((yy // cell) + (xx // cell)) % 2).astype(np.float32)

    fine = tz.extract_features(tz.load_image(checker(2), dpi=254), tamura=True)
    coarse = tz.extract_features(tz.load_image(checker(16), dpi=254), tamura=True)
    assert coarse.coarseness_m > 2 * fine.coarseness_m
    stripes = tz.extract_features(tz.load_image(grating_array((256, 256), 800, 30, 300)), tamura=True)
    assert stripes.directionality > 0.8


def test_stack_analysis_equals_one_by_one(make_grating):
    arrs = [make_grating((64, 64), f, a, 300) for f, a in ((500, 0), (1500, 80), (900, 140))]
    pitch = (0.0254 / 300,) * 2
    together = analyse_stack(np.stack(arrs), pitch)
    for arr, feat in zip(arrs, together):
        alone = tz.extract_features(tz.load_image(arr, dpi=300))
        assert feat.spatial_frequency_per_m == pytest.approx(alone.spatial_frequency_per_m, rel=1e-6)
        assert feat.spectral_intensity == pytest.approx(alone.spectral_intensity, rel=1e-6)


def test_vertical_stripes_have_orientation_zero_not_180():
    arr = grating_array((128, 128), 800.0, 0.0, 300, quantise=False, phase=0.0)
    feat = tz.extract_features(tz.load_image(arr, dpi=300))
    assert 0.0 <= feat.orientation_deg < 180.0
    assert _angle_error(feat.orientation_deg, 0.0) < 0.5


def _numpy_reference(img: np.ndarray) -> dict[str, float]:
    """The spectral definitions of TextureFeatures computed plainly in float64 NumPy
    over the *full* 2-D spectrum (no half-spectrum weights, no compiled pass)."""
    h, w = img.shape
    win = np.outer(0.5 - 0.5 * np.cos(2 * np.pi * np.arange(h) / h), 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(w) / w))
    mean = float(img.mean())
    power = np.abs(np.fft.fft2((img - mean) * win)) ** 2
    power[0, 0] = 0.0
    ky = -np.fft.fftfreq(h)[:, None]  # y up
    kx = np.fft.fftfreq(w)[None, :]
    r2 = kx**2 + ky**2
    r2[0, 0] = 1.0
    # A Nyquist frequency is +1/2 and -1/2 at once: no sign, so no share of the kx ky sums.
    kx_signed = np.where(np.abs(kx) == 0.5, 0.0, kx)
    ky_signed = np.where(np.abs(ky) == 0.5, 0.0, ky)
    s0 = power.sum()
    return {
        "mean": mean,
        "variance": s0 / (h * w) ** 2 / (3 / 8) ** 2,
        "mxx": (power * kx**2).sum() / s0,
        "myy": (power * ky**2).sum() / s0,
        "mxy": (power * kx_signed * ky_signed).sum() / s0,
        "txx": (power * kx**2 / r2).sum() / s0,
        "tyy": (power * ky**2 / r2).sum() / s0,
        "txy": (power * kx_signed * ky_signed / r2).sum() / s0,
    }


@pytest.mark.parametrize("shape", [(64, 64), (48, 75), (33, 40), (128, 96)])
@pytest.mark.parametrize("dtype", ["uint8", "float32", "float64"])
def test_compiled_sums_equal_the_plain_numpy_definitions(shape, dtype):
    rng = np.random.default_rng(sum(shape))
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    # a grating under noise plus a slope: power everywhere, several directions
    img = 0.45 + 0.2 * np.cos(2 * np.pi * (0.11 * xx - 0.07 * yy)) + 0.1 * rng.standard_normal(shape) + 0.001 * xx
    img = np.clip(img, 0, 1)
    if dtype == "uint8":
        stored, scale = np.round(img * 255).astype(np.uint8), 1 / 255
        img = stored / 255.0
    else:
        stored, scale = img.astype(dtype), 1.0
        img = stored.astype(np.float64)
    feat = analyse_stack(stored, (1e-4, 1e-4), scale=scale)[0]
    ref = _numpy_reference(img)
    assert feat.mean_level == pytest.approx(ref["mean"], rel=1e-5)
    assert feat.contrast == pytest.approx(math.sqrt(ref["variance"]), rel=1e-4)
    for got, key in zip(feat.spectral_moments_per_px2, ("mxx", "myy", "mxy")):
        assert got == pytest.approx(ref[key], rel=1e-4, abs=1e-7)
    for got, key in zip(feat.orientation_tensor, ("txx", "tyy", "txy")):
        assert got == pytest.approx(ref[key], rel=1e-4, abs=1e-6)


@pytest.mark.parametrize("cycles", [1.0, 2.0, 3.0])
def test_a_texture_a_few_cycles_across_is_exact_next_to_dc(cycles):
    # The peak's neighbours include DC and the bins the mean's removal touches;
    # at one cycle the tone leaks into the windowed DC bin, which is why the mean
    # removed is the plain one (read off the DC bin, this read 1.5 cycles).
    h, w = 64, 80
    yy, xx = np.mgrid[0:h, 0:w]
    img = (0.5 + 0.3 * np.cos(2 * np.pi * (cycles * xx / w))).astype(np.float32)
    feat = analyse_stack(img, (1e-4, 1e-4))[0]
    assert feat.wave_vector_per_px[0] == pytest.approx(cycles / w, rel=1e-6)
    assert feat.wave_vector_per_px[1] == pytest.approx(0.0, abs=1e-9)
    assert feat.peak_amplitude == pytest.approx(0.3, rel=1e-5)
    assert feat.mean_level == pytest.approx(0.5, rel=1e-6)


def test_the_peak_is_the_strongest_bin_not_dc():
    h, w = 64, 80
    # Noise: the reported bin is NumPy's argmax of the windowed power, away from DC.
    rng = np.random.default_rng(5)
    noise = rng.random((h, w)).astype(np.float32)
    ref_power = np.abs(np.fft.rfft2((noise - _numpy_reference(noise)["mean"]) * np.outer(
        0.5 - 0.5 * np.cos(2 * np.pi * np.arange(h) / h), 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(w) / w)))) ** 2
    ref_power[0, 0] = 0.0
    iy, ix = np.unravel_index(np.argmax(ref_power), ref_power.shape)
    got = analyse_stack(noise, (1e-4, 1e-4))[0].wave_vector_per_px
    assert round(got[0] * w) == ix
    assert round(-got[1] * h) % h == iy


def test_tile_views_give_the_same_features_as_copies():
    rng = np.random.default_rng(9)
    levels = rng.integers(0, 256, (96, 128), dtype=np.uint8)
    view = levels.reshape(3, 32, 4, 32).swapaxes(1, 2)[:, :, 4:28, 4:28]
    assert not view.flags.c_contiguous
    a = analyse_stack(view, (1e-4, 1e-4), scale=1 / 255)
    b = analyse_stack(np.ascontiguousarray(view), (1e-4, 1e-4), scale=1 / 255)
    assert [f.wave_vector_per_px for f in a] == [f.wave_vector_per_px for f in b]
    assert [f.contrast for f in a] == [f.contrast for f in b]


def test_mean_level_is_the_plain_mean_of_an_uneven_picture():
    # Brighter on the right: a window-weighted mean would favour the centre columns.
    h, w = 96, 128
    yy, xx = np.mgrid[0:h, 0:w]
    img = np.clip(0.2 + 0.6 * (xx / w) ** 3 + 0.1 * np.cos(2 * np.pi * xx / 8), 0, 1).astype(np.float32)
    feat = tz.extract_features(tz.load_image(img, dpi=300))
    assert feat.mean_level == pytest.approx(float(img.mean()), rel=1e-6)
    levels = np.round(img * 255).astype(np.uint8)
    assert tz.extract_features(tz.load_image(levels, dpi=300)).mean_level == pytest.approx(levels.mean() / 255, rel=1e-6)
