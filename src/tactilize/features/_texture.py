"""TextureFeatures: what the Fourier transform says about a texture, in physical units."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..image import pitch_pair

__all__ = ["NO_PEAK", "TextureFeatures"]


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
        unnormalised DFT of the image as 8-bit grey [1]_.  It grows with image
        size; use ``modulation_depth`` to compare sizes.
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

    References
    ----------
    .. [1] docs/references.md, section 1: the paper's laws and its spectral
       intensity i_s.
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

    def at_pitch(self, pitch_m: float | tuple[float, float]) -> TextureFeatures:
        """The same texture displayed at another pixel pitch [m]; no new FFT."""
        px, py = pitch_pair(pitch_m)
        if not (px > 0 and py > 0 and math.isfinite(px) and math.isfinite(py)):
            raise ValueError(f"pitch must be positive and finite, got {pitch_m!r}")
        return dataclasses.replace(self, pitch_m=(float(px), float(py)))

    def at_dpi(self, dpi: float) -> TextureFeatures:
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
