"""From a stack of images to their spectra, and from the spectra to the features.

The hot work is three passes: the window (compiled), the FFT (scipy) and one
pass over each spectrum that fills power-weighted sums and finds the
strongest bin (compiled, :func:`spectrum_sums`).  Everything else is a handful
of numbers per image, computed here in NumPy over the whole stack at once
(arrays of shape (B,), one entry per image): a texture map's dozens of tiles
cost one call of each function, not one per tile.

Frequencies are in cycles/pixel.  A spectrum row index runs *down* the
picture, like the image's rows; the features are reported with y *up*, and
the one place each sign flips says so.
"""

from __future__ import annotations

import math
import threading
from functools import lru_cache
from typing import NamedTuple

import numpy as np
import scipy.fft

__all__ = [
    "FLAT_VARIANCE",
    "HANN_COHERENT_GAIN_2D",
    "HANN_POWER_GAIN_2D",
    "SpectrumSums",
    "axis_neighbours",
    "grey_variance",
    "hann_offset",
    "hann_response",
    "is_flat",
    "normalised_moments",
    "orientation_tensor",
    "peak_bins",
    "peak_neighbourhood",
    "periodicity",
    "remove_mean_near_dc",
    "sinusoid_amplitude",
    "spectral_intensity",
    "spectrum_sums",
    "windowed_rfft2",
]

#: Coherent gain of the 2-D periodic Hann window (mean of the window, 1/2 per
#: axis): a windowed tone's DFT peak is this share of the unwindowed one.
HANN_COHERENT_GAIN_2D = 0.25

#: Power gain of the 2-D periodic Hann window (mean of its square, 3/8 per
#: axis): the windowed image's power is this share of the unwindowed one.
HANN_POWER_GAIN_2D = (3.0 / 8.0) ** 2

#: Grey-level variance at or below which an image counts as constant: a
#: thousandth of the 8-bit quantisation noise power (1/255)^2 / 12.
FLAT_VARIANCE = (1.0 / 255.0) ** 2 / 12.0 * 1e-3

#: Grey levels of the paper's 8-bit images: i_s is defined on their DFT.
_LEVELS = 255.0


# ------------------------------------------------------------------ window and FFT


@lru_cache(maxsize=32)
def _window_axes(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """The separable periodic Hann window's two factors, float32 (H,) and (W,).

    Periodic, not symmetric, so its DFT is exactly three taps per axis: the
    mean's removal touches 3 x 2 stored bins and the sub-bin refinement is exact.
    """
    wy = (0.5 - 0.5 * np.cos(2 * np.pi * np.arange(h) / h)).astype(np.float32)
    wx = (0.5 - 0.5 * np.cos(2 * np.pi * np.arange(w) / w)).astype(np.float32)
    wy.setflags(write=False)
    wx.setflags(write=False)
    return wy, wx


#: Largest windowed stack [pixels] whose buffer is kept between calls (4 bytes
#: a pixel: 16 MB); larger ones get a fresh array and give it back.
_SCRATCH_MAX_PX = 1 << 22

_SCRATCH = threading.local()


def windowed_rfft2(stack: np.ndarray, scale: float = 1.0, workers: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """rfft2 of every Hann-windowed image of a stack, and each image's plain mean.

    Parameters
    ----------
    stack : ndarray, shape (..., H, W)
        Images of any real dtype and any strides (a grid of tile views, shape
        (rows, cols, H, W), is read in place); taken in C order of the leading axes.
    scale : float
        Factor from stored values to grey levels, applied with the window
        (1/255 analyses 8-bit levels without a float copy of the image).
    workers : int
        Threads for the FFT (``scipy.fft``'s ``workers``).

    Returns
    -------
    spec : complex64 ndarray, shape (B, H, W // 2 + 1)
        The half spectra, B the product of the leading axes.
    means : float64 ndarray, shape (B,)
        Each image's mean grey level (every pixel alike, not windowed).
    """
    from . import _kernels  # numba: loaded on the first analysis, not on import

    if stack.dtype not in (np.uint8, np.float32, np.float64):
        stack = stack.astype(np.float32)  # rare dtypes (16-bit, integers) are not worth a compiled variant each
    if stack.ndim == 2:
        stack = stack[None]
    *lead, h, w = stack.shape
    b = math.prod(lead)
    wy, wx = _window_axes(h, w)
    if scale != 1.0:
        wx = wx * np.float32(scale)
    size = b * h * w
    if size <= _SCRATCH_MAX_PX:
        # One per-thread buffer, as large as the largest stack so far, so that a
        # catalog's alternating whole images and tile stacks reuse it (a fresh 3 MB
        # array costs its page faults every time).  Nothing returned points into it.
        buf = getattr(_SCRATCH, "windowed", None)
        if buf is None or buf.size < size:
            buf = _SCRATCH.windowed = np.empty(size, np.float32)
        windowed = buf[:size].reshape(b, h, w)
    else:
        windowed = np.empty((b, h, w), np.float32)
    # One call per run of the last leading axis: a grid of tile views (rows, cols, H, W)
    # cannot be merged into one axis without a copy.
    run = lead[-1]
    totals = np.empty(b)
    for k, idx in enumerate(np.ndindex(*lead[:-1])):
        block = slice(k * run, (k + 1) * run)
        _kernels.window_into(stack[idx], wy, wx, windowed[block], totals[block])
    spec = scipy.fft.rfft2(windowed, workers=workers, overwrite_x=True)
    return spec, totals * (scale / (h * w))


def remove_mean_near_dc(spec: np.ndarray, means: np.ndarray, w: int) -> None:
    """Remove each image's mean from its windowed spectrum, in place.

    A constant c under the periodic Hann window has, per axis of length N,
    the DFT taps (N/2, -N/4, -N/4) on bins (0, +1, -1) and nothing else, so
    the mean lives in rows (0, 1, H - 1) and stored columns (0, 1) only, all
    real.  The plain mean is removed, not the windowed DC bin: a texture one
    cycle across leaks into that bin, and its peak read 1.5 cycles.

    Parameters
    ----------
    spec : complex64 ndarray, shape (B, H, W // 2 + 1), modified
        Half spectra of Hann-windowed images (:func:`windowed_rfft2`).
    means : float64 ndarray, shape (B,)
        Each image's mean grey level.
    w : int
        Width of the images [pixels] (the stored width does not tell an odd
        width from the even one below it).
    """
    rows, columns, taps_y, taps_x = _dc_taps(spec.shape[1], w)
    share = means[:, None, None] * taps_y * taps_x
    # Rounded to float32 before subtracting, as the spectrum is float32.
    spec.real[:, rows, columns] -= share.astype(np.float32)


@lru_cache(maxsize=32)
def _dc_taps(h: int, w: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where a windowed constant of 1 lands in a half spectrum, and with what value.

    Returns rows (3, 1) and columns (1, 2) as index arrays, and the window's
    DFT taps along y (3, 1) and x (1, 2), whose product is the constant's DFT.
    """
    rows = np.array([[0], [1], [h - 1]])
    columns = np.array([[0, 1]])
    taps_y = np.array([[h / 2.0], [-h / 4.0], [-h / 4.0]])
    taps_x = np.array([[w / 2.0, -w / 4.0]])
    for a in (rows, columns, taps_y, taps_x):
        a.setflags(write=False)
    return rows, columns, taps_y, taps_x


@lru_cache(maxsize=32)
def _ky_down(h: int) -> np.ndarray:
    """Signed vertical frequency of each spectrum row [cycles/pixel]; rows run down the picture."""
    out = scipy.fft.fftfreq(h)
    out.setflags(write=False)
    return out


class SpectrumSums(NamedTuple):
    """What the one compiled pass over a stack of spectra reads off them.

    P = |F|^2 over the full spectrum of each image, DC left out, frequencies
    in cycles/pixel with y *down* (see :func:`_kernels.spectrum_sums`).
    """

    power: np.ndarray
    """float64 (B,): sum P, the AC power of the windowed image."""
    moments: np.ndarray
    """float64 (B, 3): sum P kx^2, sum P ky^2, sum P kx ky (Nyquist unsigned)."""
    double_angle: np.ndarray
    """float64 (B, 2): sum P cos 2t, sum P sin 2t, t the angle of the wave vector."""
    peak_index: np.ndarray
    """int64 (B,): flat index into the half spectrum of the strongest bin."""


def spectrum_sums(spec: np.ndarray, w: int) -> SpectrumSums:
    """Power-weighted sums over each spectrum of a stack, and its strongest bin (one compiled pass).

    Parameters
    ----------
    spec : complex64 ndarray, shape (B, H, W // 2 + 1), C-contiguous
        Half spectra, the mean removed (:func:`remove_mean_near_dc`).
    w : int
        Width of the images [pixels].

    Returns
    -------
    SpectrumSums
    """
    from . import _kernels

    b, h, _ = spec.shape
    sums = SpectrumSums(np.empty(b), np.empty((b, 3)), np.empty((b, 2)), np.empty(b, np.int64))
    _kernels.spectrum_sums(spec.view(np.float32), w, _ky_down(h), *sums)
    return sums


# ------------------------------------------------------------------ the dominant peak
#
# Quantities along both axes are (B, 2) arrays in (x, y) order, y *down* the
# picture like the spectrum's rows.


def peak_bins(peak_index: np.ndarray, h: int, w: int) -> np.ndarray:
    """Signed bin of each image's strongest bin.

    Parameters
    ----------
    peak_index : int ndarray, shape (B,)
        Flat index into the half spectrum, shape (H, W // 2 + 1).
    h, w : int
        Shape of the images [pixels].

    Returns
    -------
    int64 ndarray, shape (B, 2)
        (column, row) in bins: column in [0, W/2], row in (-H/2, H/2], y down.
    """
    row, column = np.divmod(peak_index, w // 2 + 1)
    return np.stack([column, np.where(row <= h // 2, row, row - h)], axis=1)


_STEPS = np.array([-1, 0, 1])


def peak_neighbourhood(spec: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """|F| on the 3 x 3 bins around each image's peak.

    Parameters
    ----------
    spec : complex ndarray, shape (B, H, W // 2 + 1)
        Half spectra.
    bins : int ndarray, shape (B, 2)
        Signed (column, row) of each peak (:func:`peak_bins`).

    Returns
    -------
    float64 ndarray, shape (B, 3, 3)
        ``out[b, 1 + dy, 1 + dx]`` = |F(row + dy, column + dx)|, rows running
        down.  A bin left of the stored half is read off its mirror (the
        spectrum of a real image is Hermitian: F(-k) = conj F(k)).  DC counts
        as 0, and so do bins right of the stored half: past the Nyquist
        frequency they are aliases, not neighbours.
    """
    b, h, nc = spec.shape
    x = bins[:, 0, None, None] + _STEPS[None, None, :]
    y = bins[:, 1, None, None] + _STEPS[None, :, None]
    mirrored = x < 0
    y = np.where(mirrored, -y, y) % h
    x = np.abs(x)
    counted = (x < nc) & ((y != 0) | (x != 0))
    values = spec[np.arange(b)[:, None, None], y, np.minimum(x, nc - 1)]
    return np.where(counted, np.abs(values.astype(np.complex128)), 0.0)


def axis_neighbours(around: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The peak's neighbours along each axis, from its 3 x 3 block.

    Parameters
    ----------
    around : float ndarray, shape (B, 3, 3)
        From :func:`peak_neighbourhood`.

    Returns
    -------
    before, after : float ndarray, shape (B, 2)
        (left, up) and (right, down): the bins one step before and after the
        peak along x and along y (y down).
    """
    return around[:, [1, 0], [0, 1]], around[:, [1, 2], [2, 1]]


def hann_offset(before: np.ndarray, peak: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Sub-bin offset of a tone from three Hann-windowed DFT magnitudes along an axis.

    For a periodic Hann window and a single tone d bins past the peak bin
    (0 <= d <= 1/2), the next bin's magnitude over the peak's is
    a = |W(1 - d)| / |W(d)| = (1 + d) / (2 - d), with |W| of
    :func:`hann_response`; so the larger neighbour gives the offset,
    d = (2a - 1) / (a + 1).  Exact for the continuous window's response; on
    a DFT of N bins the error falls as 1/N^4 (5e-8 bin at N = 64).

    Parameters
    ----------
    before, after : float ndarray, shape (B, 2)
        |F| one bin before and after the peak along x and y (:func:`axis_neighbours`).
    peak : float ndarray, shape (B, 1)
        |F| at the peak.

    Returns
    -------
    float64 ndarray, shape (B, 2)
        Offset [bins] in [-1/2, 1/2] along x and y, towards the larger
        neighbour; 0 where ``peak`` is 0.
    """
    towards_after = after >= before
    neighbour = np.where(towards_after, after, before)
    ratio = np.divide(neighbour, peak, out=np.zeros(neighbour.shape), where=peak > 0)
    d = np.clip((2.0 * ratio - 1.0) / (ratio + 1.0), 0.0, 0.5)
    return np.where(towards_after, d, -d)


def hann_response(d: np.ndarray) -> np.ndarray:
    """|DFT| of a periodic Hann window ``d`` bins from its centre, normalised to 1 at 0.

    sin(pi d) / (pi d) / (1 - d^2), for |d| < 1: the scalloping loss of a
    tone ``d`` bins off the bin it is read at (the continuous window's
    response; on a DFT of N bins it is off by less than 1e-7 from N = 64).
    """
    return np.sinc(d) / (1.0 - d * d)


def sinusoid_amplitude(peak: np.ndarray, offset: np.ndarray, n: int) -> np.ndarray:
    """Amplitude [grey levels] of the sinusoid behind a Hann-windowed DFT peak.

    A sinusoid of amplitude A over N pixels puts A N / 2 in each of its two
    mirror bins; the window scales that by its coherent gain and by its
    response at the tone's offset from the bin (scalloping), undone here.

    Parameters
    ----------
    peak : float ndarray, shape (B,)
        |F| of the windowed image at the peak bin.
    offset : float ndarray, shape (B, 2)
        The tone's offset from that bin along x and y [bins] (:func:`hann_offset`).
    n : int
        Number of pixels of each image.

    Returns
    -------
    float64 ndarray, shape (B,)
    """
    response = hann_response(offset).prod(axis=1)
    return 2.0 * peak / (n * HANN_COHERENT_GAIN_2D * response)


def spectral_intensity(amplitude: np.ndarray, mean: np.ndarray, n_pixels: int) -> np.ndarray:
    """The paper's spectral intensity i_s of a dominant sinusoid.

    i_s = ln(1 + |F(k*)|) / ln(1 + |F(0)|) for the unnormalised DFT F of the
    image as 8-bit grey levels [1]_: |F(0)| = 255 mean N and, for a sinusoid
    of amplitude A, |F(k*)| = 255 A N / 2 (the value on its bin, whatever the
    window and the bin grid did to the measured peak).

    Parameters
    ----------
    amplitude : float ndarray, shape (B,)
        Amplitude of the dominant sinusoid [grey levels in [0, 1]].
    mean : float ndarray, shape (B,)
        Mean grey level [0, 1].
    n_pixels : int
        N, the number of pixels the DFT sums: i_s grows with it.

    Returns
    -------
    float64 ndarray, shape (B,)
        i_s clipped to [0, 1]; 0 for a black image (|F(0)| = 0).

    References
    ----------
    .. [1] docs/references.md, section 1: the paper's laws and i_s.
    """
    dc = _LEVELS * mean * n_pixels
    peak = _LEVELS * 0.5 * amplitude * n_pixels
    lit = dc > 0
    ratio = np.log1p(peak) / np.log1p(np.where(lit, dc, 1.0))
    return np.where(lit, np.clip(ratio, 0.0, 1.0), 0.0)


def periodicity(neighbourhood: np.ndarray, power: np.ndarray) -> np.ndarray:
    """Share of the AC power in the dominant peak, in [0, 1].

    Parameters
    ----------
    neighbourhood : float ndarray, shape (B, 3, 3)
        |F| around the peak (:func:`peak_neighbourhood`); the window spreads a
        tone over these bins.
    power : float ndarray, shape (B,)
        Total AC power over the full spectrum (:attr:`SpectrumSums.power`).

    Returns
    -------
    float64 ndarray, shape (B,)
        Twice the block's power (its mirror at -k holds as much again) over
        the total: ~1 for a pure grating, ~0 for white noise.
    """
    peak_power = np.square(neighbourhood).sum(axis=(1, 2))
    return np.minimum(1.0, 2.0 * peak_power / _nonzero(power))


def grey_variance(power: np.ndarray, n: int) -> np.ndarray:
    """Variance of the grey levels [grey levels^2], by Parseval from the windowed AC power.

    sum |F|^2 = N sum x^2 for the DFT, and the window keeps
    :data:`HANN_POWER_GAIN_2D` of the power, so the variance is
    sum P / (N^2 gain).  Its square root is the RMS contrast.

    Parameters
    ----------
    power : float ndarray, shape (B,)
        Total AC power of the windowed images (:attr:`SpectrumSums.power`).
    n : int
        Number of pixels of each image.

    Returns
    -------
    float64 ndarray, shape (B,)
    """
    return power / (n * n * HANN_POWER_GAIN_2D)


def is_flat(variance: np.ndarray, power: np.ndarray) -> np.ndarray:
    """True for images with no AC content, shape (B,): reported as :data:`NO_PEAK`.

    A variance at or below :data:`FLAT_VARIANCE` is rounding, not texture.
    """
    return (variance <= FLAT_VARIANCE) | (power <= 0)


def normalised_moments(moments: np.ndarray, power: np.ndarray) -> np.ndarray:
    """<kx^2>, <ky^2>, <kx ky> of the AC power spectrum [cycles^2/pixel^2], y up.

    Parameters
    ----------
    moments : float ndarray, shape (B, 3)
        The power-weighted sums, y down (:attr:`SpectrumSums.moments`).
    power : float ndarray, shape (B,)
        Their weight, sum P.

    Returns
    -------
    float64 ndarray, shape (B, 3)
    """
    out = moments / _nonzero(power)[:, None]
    out[:, 2] *= -1.0  # ky changes sign with y up; kx^2 and ky^2 do not
    return out


def orientation_tensor(double_angle: np.ndarray, power: np.ndarray) -> np.ndarray:
    """Power-weighted <cos^2 t>, <sin^2 t>, <cos t sin t> of the wave vectors' angles, y up.

    From the double-angle sums: cos^2 = (1 + cos 2t) / 2, sin^2 = (1 - cos 2t) / 2,
    cos sin = sin 2t / 2.  The spread of directions, whatever the frequency.

    Parameters
    ----------
    double_angle : float ndarray, shape (B, 2)
        sum P cos 2t and sum P sin 2t, y down (:attr:`SpectrumSums.double_angle`).
    power : float ndarray, shape (B,)
        Their weight, sum P.

    Returns
    -------
    float64 ndarray, shape (B, 3)
    """
    cos2, sin2 = (double_angle / _nonzero(power)[:, None]).T
    # sin 2t changes sign with y up; cos 2t does not
    return np.stack([0.5 + 0.5 * cos2, 0.5 - 0.5 * cos2, -0.5 * sin2], axis=1)


def _nonzero(power: np.ndarray) -> np.ndarray:
    """``power`` with its zeros (constant images, reported as NO_PEAK anyway) replaced by 1, to divide by."""
    return np.where(power > 0, power, 1.0)
