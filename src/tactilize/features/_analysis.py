"""The analysis: images in, :class:`TextureFeatures` out."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.fft

from ..image import TextureImage
from . import _spectrum as sp
from ._tamura import tamura_features
from ._texture import TextureFeatures, _no_peak

__all__ = ["MIN_SIDE_PX", "analyse_stack", "extract_features", "radial_profile", "warm_up"]

#: Images smaller than this on a side carry no measurable periodic structure.
MIN_SIDE_PX = 4


def analyse_stack(
    stack: np.ndarray,
    pitch_m: tuple[float, float],
    *,
    radial: bool = False,
    workers: int = 1,
    scale: float = 1.0,
    intensity_size: int | None = None,
) -> list[TextureFeatures]:
    """Features of every image in a stack of equal-sized grey images.

    Parameters
    ----------
    stack : ndarray, shape (..., H, W)
        Grey levels in [0, 1] after multiplying by ``scale``; any real dtype and
        any strides (a grid of tiles can be a view, shape (rows, cols, H, W)).
        Images are taken in C order of the leading axes.
    pitch_m : (float, float)
        Pixel pitch [m] shared by all images.
    radial : bool
        Also compute each image's radial power profile.
    workers : int
        Threads for the FFT (scipy.fft's ``workers``).
    scale : float
        Factor from stored values to grey levels, applied with the window
        (1/255 analyses 8-bit pixels without a float copy of the image).
    intensity_size : int, optional
        Number of pixels for which ``spectral_intensity`` is given (i_s is read
        off the DFT, whose values grow with the number of pixels summed): a
        sample of a larger region reports the region's i_s for the same
        texture.  Default: H * W.

    Returns
    -------
    list of TextureFeatures
        One per image, in order.  Used by :func:`extract_features` (B = 1) and by
        the texture map (one image per tile, one batched FFT).

    Notes
    -----
    One pass windows the images, one batched FFT transforms them and one pass
    over the spectra fills power-weighted sums and finds each strongest bin
    (:mod:`._kernels`, compiled); every number per image is then computed over
    the whole stack at once by the functions of :mod:`._spectrum`, where each
    is documented.
    """
    stack = np.asarray(stack)
    if stack.dtype.kind not in "uif":
        stack = stack.astype(np.float32)
    *lead, h, w = stack.shape
    b = math.prod(lead)
    pitch = (float(pitch_m[0]), float(pitch_m[1]))
    if h < MIN_SIDE_PX or w < MIN_SIDE_PX:
        means = stack.reshape(b, -1).mean(axis=1) * scale if h * w else np.zeros(b)
        return [_no_peak((h, w), pitch, float(m)) for m in means]

    n = h * w
    spec, mean = sp.windowed_rfft2(stack, scale, workers)
    sp.remove_mean_near_dc(spec, mean, w)
    sums = sp.spectrum_sums(spec, w)

    bins = sp.peak_bins(sums.peak_index, h, w)
    around = sp.peak_neighbourhood(spec, bins)
    peak = around[:, 1, 1]
    before, after = sp.axis_neighbours(around)
    offset = sp.hann_offset(before, peak[:, None], after)
    amplitude = sp.sinusoid_amplitude(peak, offset, n)
    wave_vector = (bins + offset) / np.array([w, h])
    wave_vector[:, 1] *= -1.0  # rows run down the picture; the wave vector is reported y up
    i_s = sp.spectral_intensity(amplitude, mean, n if intensity_size is None else int(intensity_size))
    variance = sp.grey_variance(sums.power, n)

    columns = zip(
        sp.is_flat(variance, sums.power).tolist(),
        mean.tolist(),
        wave_vector.tolist(),
        i_s.tolist(),
        amplitude.tolist(),
        sp.periodicity(around, sums.power).tolist(),
        np.sqrt(np.maximum(variance, 0.0)).tolist(),  # RMS contrast
        sp.normalised_moments(sums.moments, sums.power).tolist(),
        sp.orientation_tensor(sums.double_angle, sums.power).tolist(),
        _radial_profiles(spec, h, w) if radial else [None] * b,
    )
    out: list[TextureFeatures] = []
    for flat, m, k, i_si, a, per, con, moments, tensor, profile in columns:
        if flat:
            out.append(dataclasses.replace(_no_peak((h, w), pitch, m), radial=profile))
            continue
        out.append(
            TextureFeatures(
                wave_vector_per_px=tuple(k),
                pitch_m=pitch,
                shape=(h, w),
                spectral_intensity=i_si,
                peak_amplitude=a,
                mean_level=m,
                periodicity=per,
                contrast=con,
                spectral_moments_per_px2=tuple(moments),
                orientation_tensor=tuple(tensor),
                radial=profile,
            )
        )
    return out


def _radial_profiles(spec: np.ndarray, h: int, w: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Mean power |F|^2 in rings one bin wide, radius in cycles/pixel (square pixels assumed).

    Parameters
    ----------
    spec : complex ndarray, shape (B, H, W // 2 + 1)
        Half spectra, the mean removed; DC is left out.

    Returns
    -------
    list of (radius, power)
        One per image: the rings' radii [cycles/pixel], increasing, and their
        mean power, both float64 (R,), rings with no bin left out.
    """
    power = np.square(np.abs(spec).astype(np.float32))
    power[:, 0, 0] = 0.0
    ky = scipy.fft.fftfreq(h)[:, None]
    kx = (np.arange(w // 2 + 1) / w)[None, :]
    r = np.hypot(kx, ky)
    step = 1.0 / max(h, w)
    ring = np.minimum((r / step).astype(np.int64), int(0.5 / step)).ravel()
    counts = np.bincount(ring)
    centres = np.arange(len(counts)) * step
    keep = counts > 0
    out = []
    for p in power:
        sums = np.bincount(ring, weights=p.ravel().astype(np.float64), minlength=len(counts))
        out.append((centres[keep], sums[keep] / counts[keep]))
    return out


def extract_features(
    img: TextureImage,
    *,
    radial: bool = False,
    tamura: bool = False,
    workers: int = 1,
) -> TextureFeatures:
    """Measure the texture features of an image.

    Parameters
    ----------
    img : TextureImage
        From :func:`tactilize.load_image` (grey float32 in [0, 1] with pitch).
    radial : bool
        Also keep the radial power spectrum (for plots; see :func:`radial_profile`).
    tamura : bool
        Also compute Tamura coarseness and directionality (on a copy reduced to
        at most 256 pixels a side, since they describe element size, not detail).
    workers : int
        FFT threads.

    Returns
    -------
    TextureFeatures
        ``spatial_frequency_per_m`` [cycles/m], ``spectral_intensity`` in [0, 1],
        ``orientation_deg``, ``anisotropy``, ``modulation_depth`` and more.  A
        constant image gives :data:`NO_PEAK`'s values (all 0, never NaN); white
        noise gives its strongest bin with ``periodicity`` near 0.
    """
    data, scale = img.analysis_data()
    feat = analyse_stack(data, img.pitch_m, radial=radial, workers=workers, scale=scale)[0]
    if tamura:
        feat = dataclasses.replace(feat, tamura=tamura_features(img.pixels))
    return feat


def radial_profile(img: TextureImage) -> tuple[np.ndarray, np.ndarray]:
    """Radial power spectrum of an image.

    Returns
    -------
    frequency : float64 ndarray, shape (R,)
        Ring radius [cycles/m], increasing.
    power : float64 ndarray, shape (R,)
        Mean |F|^2 of the windowed, mean-removed image over the ring.
    """
    return extract_features(img, radial=True).radial_profile_per_m()  # type: ignore[return-value]


def warm_up() -> None:
    """Make the analysis' compiled passes ready in this process, for the usual inputs.

    The first analysis in a process loads them from numba's on-disk cache (a
    few tenths of a second; on a machine's first run it compiles them, a few
    seconds).  A process pool calls this in its parent before its workers
    fork, so that none of them pays it again; a worker started another way
    calls it once when it starts.  Covers 8-bit levels and float32 and
    float64 pixels, whole and as tile views (the layouts texture maps pass).
    """
    y, x = np.mgrid[0:64, 0:64]
    grating = (0.5 + 0.4 * np.cos(2 * np.pi * (x / 8.0 + y / 16.0))).astype(np.float32)
    for pixels, scale in ((np.round(grating * 255).astype(np.uint8), 1 / 255), (grating, 1.0), (grating.astype(np.float64), 1.0)):
        tiles = pixels.reshape(2, 32, 2, 32).swapaxes(1, 2)
        analyse_stack(pixels, (1e-4, 1e-4), scale=scale)
        analyse_stack(tiles[:, :, 8:24, 8:24], (1e-4, 1e-4), scale=scale)
