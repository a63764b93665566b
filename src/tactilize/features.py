"""Texture features from the 2-D Fourier transform of an image.

The paper extracts two numbers from an image's Fourier transform: the spatial
frequency of its dominant periodic component, ``f_s`` [cycles/m], and that
component's *spectral intensity* ``i_s`` in [0, 1] (FACTS.md section 1).  This
module measures them, plus what the paper names as future work: descriptors
of textures that are not periodic (contrast, roughness, orientation and
anisotropy, Tamura coarseness and directionality).

Everything is measured in cycles per pixel and converted to cycles per metre
with the image's pixel pitch, so :meth:`TextureFeatures.at_pitch` gives the
same texture shown at another size without a new FFT.

Conventions
-----------
Angles are counter-clockwise from the image's +x axis (rightwards) with y
pointing *up* the picture, in degrees for ``orientation_deg``.  The wave vector
is perpendicular to the ridges of a grating: vertical stripes have orientation 0.
"""

from __future__ import annotations

import dataclasses
import math
import threading
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
import scipy.fft

from .image import TextureImage

__all__ = ["TextureFeatures", "extract_features", "analyse_stack", "radial_profile", "warm_up", "NO_PEAK"]

#: Images smaller than this on a side carry no measurable periodic structure.
MIN_SIDE_PX = 4

#: below this fraction of the 8-bit quantisation noise power the image counts as constant
_FLAT_VARIANCE = (1.0 / 255.0) ** 2 / 12.0 * 1e-3



@dataclass(frozen=True)
class TextureFeatures:
    """What the Fourier transform says about a texture.

    Stored in per-pixel units with the pitch they were measured at; every
    physical value is a property, so :meth:`at_pitch` rescales for free.

    Attributes
    ----------
    wave_vector_per_px : (float, float)
        Dominant wave vector (kx, ky) [cycles/pixel], y up, refined below one
        bin.  (0, 0) when the image has no periodic content.
    pitch_m : (float, float)
        (x, y) pixel pitch [m] of the displayed image.
    shape : (int, int)
        (height, width) [pixels] of the analysed image.
    spectral_intensity : float
        The paper's i_s in [0, 1]: ln(1 + |F(k*)|) / ln(1 + |F(0)|) for the
        unnormalised DFT of the image as 8-bit grey (FACTS.md section 1).  It
        grows with image size; use ``modulation_depth`` to compare sizes.
    peak_amplitude : float
        Amplitude of the dominant sinusoid in grey levels (0..0.5 for [0, 1]).
    mean_level : float
        Mean grey level in [0, 1] (plain: every pixel counts alike; it is
        F(0) / N, the DC term of the paper's i_s).
    periodicity : float
        Share of the (windowed) AC power in the dominant peak, in [0, 1]:
        ~1 for a pure grating, ~0 for white noise.  Size-independent.
    contrast : float
        RMS contrast: standard deviation of grey levels (windowed estimate).
    spectral_moments_per_px2 : (float, float, float)
        <kx^2>, <ky^2>, <kx ky> of the AC power spectrum [cycles^2/pixel^2].
    orientation_tensor : (float, float, float)
        Power-weighted <cos^2>, <sin^2>, <cos sin> of the wave vectors' angles
        (pixel frame, y up): the spread of directions, whatever their frequency.
    radial : tuple of ndarray or None
        (radius [cycles/pixel], mean power) when asked for.
    tamura : dict or None
        ``coarseness_px`` and ``directionality`` when asked for.
    """

    wave_vector_per_px: tuple[float, float]
    pitch_m: tuple[float, float]
    shape: tuple[int, int]
    spectral_intensity: float
    peak_amplitude: float
    mean_level: float
    periodicity: float
    contrast: float
    spectral_moments_per_px2: tuple[float, float, float]
    orientation_tensor: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radial: tuple[np.ndarray, np.ndarray] | None = field(default=None, compare=False, repr=False)
    tamura: dict[str, float] | None = field(default=None, compare=False)

    # -------------------------------------------------------------- physical values

    @property
    def has_peak(self) -> bool:
        """False for images with no AC content at all (constant, or too small)."""
        return self.wave_vector_per_px != (0.0, 0.0)

    @property
    def wave_vector_per_m(self) -> tuple[float, float]:
        """Dominant wave vector [cycles/m], y up."""
        return (self.wave_vector_per_px[0] / self.pitch_m[0], self.wave_vector_per_px[1] / self.pitch_m[1])

    @property
    def spatial_frequency_per_m(self) -> float:
        """Dominant spatial frequency f_s [cycles/m] of the displayed image; 0 when none."""
        kx, ky = self.wave_vector_per_m
        return math.hypot(kx, ky)

    @property
    def wavelength_m(self) -> float:
        """Period of the dominant component [m]; ``inf`` when there is none."""
        f = self.spatial_frequency_per_m
        return 1.0 / f if f > 0 else math.inf

    @property
    def orientation_deg(self) -> float:
        """Direction of the dominant wave vector [deg] in [0, 180); 0 when none."""
        if not self.has_peak:
            return 0.0
        kx, ky = self.wave_vector_per_m
        angle = math.degrees(math.atan2(ky, kx)) % 180.0
        # a tiny negative angle wraps to 180.0 in floating point; the range is [0, 180)
        return 0.0 if angle >= 180.0 else angle

    @property
    def modulation_depth(self) -> float:
        """Michelson-like depth of the dominant component, amplitude / mean, in [0, 1].

        Independent of image size, unlike ``spectral_intensity``: a full-contrast
        grating 0.5 + 0.5 cos gives 1.
        """
        if self.mean_level <= 0:
            return 0.0
        return float(min(1.0, self.peak_amplitude / self.mean_level))

    def _physical_moments(self) -> tuple[float, float, float]:
        mxx, myy, mxy = self.spectral_moments_per_px2
        px, py = self.pitch_m
        return mxx / px**2, myy / py**2, mxy / (px * py)

    @property
    def anisotropy(self) -> float:
        """How much the spectral power lies along one direction, in [0, 1].

        (l1 - l2) / (l1 + l2) of the orientation tensor: 1 for a grating, ~0 for
        isotropic noise, 0 for a constant image.  Measured in the pixel frame,
        so it does not change when the picture is shown larger or smaller.
        """
        cxx, cyy, cxy = self.orientation_tensor
        tr = cxx + cyy
        if tr <= 0:
            return 0.0
        return float(min(1.0, math.sqrt((cxx - cyy) ** 2 + 4 * cxy**2) / tr))

    @property
    def rms_frequency_per_m(self) -> float:
        """Power-weighted RMS spatial frequency [cycles/m]: where the energy sits."""
        sxx, syy, _ = self._physical_moments()
        return math.sqrt(max(0.0, sxx + syy))

    @property
    def roughness_per_m(self) -> float:
        """RMS gradient of the grey level [1/m] (grey units per metre), by Parseval:
        2 pi * contrast * RMS frequency.  A non-periodic roughness measure."""
        return 2 * math.pi * self.contrast * self.rms_frequency_per_m

    @property
    def roughness_per_mm(self) -> float:
        """RMS grey-level gradient [1/mm]."""
        return self.roughness_per_m * 1e-3

    @property
    def coarseness_m(self) -> float | None:
        """Tamura coarseness [m] (typical size of texture elements), if computed."""
        if self.tamura is None:
            return None
        return self.tamura["coarseness_px"] * math.sqrt(self.pitch_m[0] * self.pitch_m[1])

    @property
    def directionality(self) -> float | None:
        """Tamura directionality in [0, 1] (1: one sharp edge direction), if computed."""
        return None if self.tamura is None else self.tamura["directionality"]

    # -------------------------------------------------------------- rescaling, export

    def at_pitch(self, pitch_m: float | tuple[float, float]) -> "TextureFeatures":
        """The same texture displayed at another pixel pitch [m]; no new FFT."""
        px, py = (pitch_m, pitch_m) if np.isscalar(pitch_m) else pitch_m  # type: ignore[misc]
        if not (px > 0 and py > 0 and math.isfinite(px) and math.isfinite(py)):
            raise ValueError(f"pitch must be positive and finite, got {pitch_m!r}")
        return dataclasses.replace(self, pitch_m=(float(px), float(py)))

    def at_dpi(self, dpi: float) -> "TextureFeatures":
        """The same texture displayed at ``dpi`` pixels per inch."""
        return self.at_pitch(0.0254 / dpi)

    def radial_profile_per_m(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(spatial frequency [cycles/m], mean power) if the profile was computed."""
        if self.radial is None:
            return None
        r, p = self.radial
        return r / math.sqrt(self.pitch_m[0] * self.pitch_m[1]), p

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready mapping, SI units plus a few mm values for display."""
        d: dict[str, Any] = {
            "spatial_frequency_per_m": self.spatial_frequency_per_m,
            "wavelength_mm": self.wavelength_m * 1e3,
            "spectral_intensity": self.spectral_intensity,
            "modulation_depth": self.modulation_depth,
            "periodicity": self.periodicity,
            "orientation_deg": self.orientation_deg,
            "anisotropy": self.anisotropy,
            "contrast": self.contrast,
            "mean_level": self.mean_level,
            "roughness_per_mm": self.roughness_per_mm,
            "rms_frequency_per_m": self.rms_frequency_per_m,
            "has_peak": self.has_peak,
            "pitch_m": list(self.pitch_m),
        }
        if self.tamura is not None:
            d["coarseness_mm"] = (self.coarseness_m or 0.0) * 1e3
            d["directionality"] = self.directionality
        if self.radial is not None:
            f, p = self.radial_profile_per_m()  # type: ignore[misc]
            d["radial_profile"] = {"spatial_frequency_per_m": f.tolist(), "power": p.tolist()}
        return d


def _no_peak(shape: tuple[int, int], pitch: tuple[float, float], mean: float) -> TextureFeatures:
    return TextureFeatures((0.0, 0.0), pitch, shape, 0.0, 0.0, float(mean), 0.0, 0.0, (0.0, 0.0, 0.0))


#: The documented values of an image with no AC content (constant): every
#: spectral value 0, orientation 0, ``has_peak`` False.  Never NaN.
NO_PEAK = _no_peak((0, 0), (1.0, 1.0), 0.0)


# ------------------------------------------------------------------ the analysis


@lru_cache(maxsize=32)
def _window_axes(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """The separable periodic Hann window's two factors, float32 (H,) and (W,).

    Periodic, not symmetric, so its DFT is exactly three taps per axis and the
    peak interpolation is exact.
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


def _windowed_rfft2(stack: np.ndarray, scale: float, workers: int) -> tuple[np.ndarray, np.ndarray]:
    """rfft2 of every Hann-windowed image in ``stack`` (shape (..., H, W)), as (B, H, W//2+1) complex64,
    and each image's plain mean (B,), read in the same pass.

    The window (separable, with ``scale`` folded into its row factor) is one
    compiled pass that reads the pixels in whatever dtype and strides they
    come (8-bit levels, float pixels, tile views) and writes float32 once;
    then one batched FFT.  ``scale`` multiplies the pixels on the way (1/255
    for 8-bit levels).
    """
    from . import _spectrum

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
        _spectrum.window_into(stack[idx], wy, wx, windowed[k * run : (k + 1) * run], totals[k * run : (k + 1) * run])
    return scipy.fft.rfft2(windowed, workers=workers, overwrite_x=True), totals * (scale / (h * w))


@lru_cache(maxsize=32)
def _ky_down(h: int) -> np.ndarray:
    """Signed vertical frequency of each spectrum row [cycles/pixel]; rows run down the picture."""
    out = scipy.fft.fftfreq(h)
    out.setflags(write=False)
    return out


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
    """
    stack = np.asarray(stack)
    if stack.dtype.kind not in "uif":
        stack = stack.astype(np.float32)
    *lead, h, w = stack.shape
    b = math.prod(lead)
    if h < MIN_SIDE_PX or w < MIN_SIDE_PX:
        means = stack.reshape(b, -1).mean(axis=1) * scale if h * w else np.zeros(b)
        return [_no_peak((h, w), pitch_m, float(m)) for m in means]

    from . import _spectrum

    spec, means = _windowed_rfft2(stack, scale, workers)
    # Everything per image in one compiled call (what each number is: TextureFeatures
    # and _spectrum.analyse_spectra); a texture map has dozens of tiles.
    table = np.empty((b, _spectrum.N_COLUMNS))
    n_is = h * w if intensity_size is None else int(intensity_size)
    _spectrum.analyse_spectra(spec.view(np.float32), w, means, _ky_down(h), _FLAT_VARIANCE, n_is, table)
    radial_profiles = _radial_from_power(_power(spec), h, w) if radial else [None] * b
    pitch = (float(pitch_m[0]), float(pitch_m[1]))
    out: list[TextureFeatures] = []
    for i, (kx, ky, i_si, a, mean, per, con, mxx, myy, mxy, txx, tyy, txy, flat) in enumerate(table.tolist()):
        if flat:
            out.append(dataclasses.replace(_no_peak((h, w), pitch, mean), radial=radial_profiles[i]))
            continue
        out.append(
            TextureFeatures(
                wave_vector_per_px=(kx, ky),
                pitch_m=pitch,
                shape=(h, w),
                spectral_intensity=i_si,
                peak_amplitude=a,
                mean_level=mean,
                periodicity=per,
                contrast=con,
                spectral_moments_per_px2=(mxx, myy, mxy),
                orientation_tensor=(txx, tyy, txy),
                radial=radial_profiles[i],
            )
        )
    return out


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


def _power(spec: np.ndarray) -> np.ndarray:
    """|F|^2 of a stack of half spectra, DC zeroed, float32."""
    power = np.abs(spec).astype(np.float32)
    np.square(power, out=power)
    power[:, 0, 0] = 0.0
    return power


def _radial_from_power(power: np.ndarray, h: int, w: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Mean power in rings one bin wide, radius in cycles/pixel (square pixels assumed)."""
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
    radial_profile: bool = False,
    tamura: bool = False,
    workers: int = 1,
) -> TextureFeatures:
    """Measure the texture features of an image.

    Parameters
    ----------
    img : TextureImage
        From :func:`tactilize.load_image` (grey float32 in [0, 1] with pitch).
    radial_profile : bool
        Also keep the radial power spectrum (for plots).
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
    feat = analyse_stack(data, img.pitch_m, radial=radial_profile, workers=workers, scale=scale)[0]
    if tamura:
        feat = dataclasses.replace(feat, tamura=tamura_features(img.pixels))
    return feat


def radial_profile(img: TextureImage) -> tuple[np.ndarray, np.ndarray]:
    """Radial power spectrum: (spatial frequency [cycles/m], mean power per ring)."""
    return extract_features(img, radial_profile=True).radial_profile_per_m()  # type: ignore[return-value]


# ------------------------------------------------------------------ Tamura


def tamura_features(pixels: np.ndarray, max_side: int = 256) -> dict[str, float]:
    """Tamura coarseness [pixels of the input] and directionality in [0, 1].

    Coarseness: for window sizes 2^k (k = 1..5), the largest difference between
    averages on opposite sides picks each pixel's best size; its mean is the
    coarseness (Tamura, Mori and Yamawaki 1978).  Directionality: 1 minus the
    spread of gradient directions around their main peak, normalised so that a
    uniform histogram gives 0 and a single direction 1.
    """
    from scipy import ndimage

    a = np.asarray(pixels, dtype=np.float32)
    factor = max(1, int(math.ceil(max(a.shape) / max_side)))
    if factor > 1:
        hh, ww = (a.shape[0] // factor) * factor, (a.shape[1] // factor) * factor
        a = a[:hh, :ww].reshape(hh // factor, factor, ww // factor, factor).mean(axis=(1, 3))
    if min(a.shape) < 8 or float(a.std()) < 1e-6:
        return {"coarseness_px": 0.0, "directionality": 0.0}

    best_e = np.zeros(a.shape, np.float32)
    best_k = np.ones(a.shape, np.float32)
    for k in range(1, 6):
        size = 2**k
        if size * 2 > min(a.shape):
            break
        avg = ndimage.uniform_filter(a, size=size, mode="reflect")
        half = size // 2
        eh = np.abs(np.roll(avg, -half, axis=1) - np.roll(avg, half, axis=1))
        ev = np.abs(np.roll(avg, -half, axis=0) - np.roll(avg, half, axis=0))
        e = np.maximum(eh, ev)
        better = e > best_e
        best_e = np.where(better, e, best_e)
        best_k = np.where(better, float(size), best_k)
    coarseness = float(best_k.mean()) * factor

    gy, gx = np.gradient(a)
    g = np.hypot(gx, gy)
    strong = g > max(1e-6, 0.1 * float(g.max()))
    if not strong.any():
        return {"coarseness_px": coarseness, "directionality": 0.0}
    theta = np.mod(np.arctan2(gy[strong], gx[strong]), np.pi)
    hist, edges = np.histogram(theta, bins=16, range=(0, np.pi), weights=g[strong])
    hist = hist / hist.sum()
    centres = 0.5 * (edges[:-1] + edges[1:])
    peak = centres[int(np.argmax(hist))]
    dist = np.abs((centres - peak + np.pi / 2) % np.pi - np.pi / 2)
    spread = float((hist * dist**2).sum())
    uniform = float((dist**2).mean())
    directionality = float(min(1.0, max(0.0, 1.0 - spread / uniform)))
    return {"coarseness_px": coarseness, "directionality": directionality}
