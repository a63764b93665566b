"""The paper's Fig. 5 as data: a picture, its 2-D Fourier spectrum, the dominant peak.

The paper shows, for each texture, the image, the log magnitude of its 2-D
Fourier transform with DC in the centre, and the dominant peak whose distance
from DC is the spatial frequency f_s and whose height gives the spectral
intensity i_s (docs/references.md, section 1 (the two laws, reading of i_s)).  The page
(``/api/textures/{id}/spectrum``) and ``tactilize analyze IMAGE --plot FILE``
draw it from :func:`spectrum_view`, so both mark the same peak as
:func:`~tactilize.features.extract_features`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..features import TextureFeatures
from .texturemap import TextureMap

__all__ = ["log_spectrum", "spectrum_view", "peak_position_px"]

#: Longest side of the spectrum image sent to the page [pixels]: the centre
#: of the spectrum is kept (cropped, not resampled, so a bin stays a bin).
MAX_SIDE = 256


def log_spectrum(pixels: np.ndarray) -> np.ndarray:
    """ln(1 + |F|) of a grey image, DC centred (``fftshift``).

    Parameters
    ----------
    pixels : ndarray, shape (h, w)
        Grey levels (any scale; the paper uses 8-bit levels).

    Returns
    -------
    ndarray, shape (h, w)
        Log magnitude; DC at row ``h // 2``, column ``w // 2``; rows run
        from the highest ky (top, y up) to the lowest.
    """
    a = np.asarray(pixels, dtype=np.float64)
    spec = np.fft.fftshift(np.abs(np.fft.fft2(a)))
    # Row 0 of an fftshift-ed spectrum is ky = -h/2 with y down in the image,
    # that is +ky with y up: the page and the plot show it as it is.
    return np.log1p(spec)


def peak_position_px(wave_vector_per_px: tuple[float, float], shape: tuple[int, int]) -> tuple[float, float]:
    """(column, row) of a wave vector in a DC-centred spectrum of ``shape``.

    Parameters
    ----------
    wave_vector_per_px : (float, float)
        (kx, ky) [cycles/pixel], y up, as in :class:`~tactilize.features.TextureFeatures`.
    shape : (int, int)
        (h, w) of the spectrum [bins].
    """
    h, w = shape
    kx, ky = wave_vector_per_px
    return (w // 2 + kx * w, h // 2 - ky * h)


def spectrum_view(
    pixels: np.ndarray, features: TextureFeatures, texture_map: TextureMap | None = None, max_side: int = MAX_SIDE
) -> dict[str, Any]:
    """Everything Fig. 5 shows, JSON-ready.

    Parameters
    ----------
    pixels : ndarray, shape (h, w)
        The grey image in [0, 1].
    features : TextureFeatures
        Its features (what the pen uses: f_s, i_s, the wave vector).
    texture_map : TextureMap, optional
        Its local map: the tiles' f_s [cycles/mm] and i_s are added.
    max_side : int
        Longest side of the returned spectrum [bins]; the centre is kept.

    Returns
    -------
    dict
        ``spectrum_u8`` (ndarray, uint8, the cropped log magnitude scaled to
        0..255), ``crop`` (rows, cols kept around DC), ``full_shape``,
        ``peak_px`` (column, row in the cropped spectrum, and its mirror
        ``mirror_px``), ``spatial_frequency_per_mm`` [cycles/mm],
        ``spectral_intensity``, ``wavelength_mm``, ``orientation_deg``,
        ``bin_per_mm`` (x, y) [cycles/mm per bin], and ``tiles`` when a map
        is given.
    """
    h, w = pixels.shape
    spec = log_spectrum(np.asarray(pixels) * 255.0)
    ch, cw = min(h, max_side), min(w, max_side)
    r0, c0 = h // 2 - ch // 2, w // 2 - cw // 2
    crop = spec[r0:r0 + ch, c0:c0 + cw]
    # Scale for display: DC alone would make everything else black.
    hi = float(np.percentile(crop, 99.9)) or 1.0
    lo = float(np.percentile(crop, 5.0))
    u8 = (np.clip((crop - lo) / max(hi - lo, 1e-12), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    col, row = peak_position_px(features.wave_vector_per_px, (h, w))
    pitch = features.pitch_m
    d: dict[str, Any] = {
        "spectrum_u8": u8,
        "crop": [ch, cw],
        "full_shape": [h, w],
        "peak": bool(features.has_peak),
        "peak_px": [col - c0, row - r0],
        # The conjugate peak -k (a real image's spectrum is point-symmetric).
        "mirror_px": [2 * (w // 2) - col - c0, 2 * (h // 2) - row - r0],
        "spatial_frequency_per_mm": features.spatial_frequency_per_m * 1e-3,
        "spectral_intensity": float(features.spectral_intensity),
        "wavelength_mm": features.wavelength_m * 1e3 if math.isfinite(features.wavelength_m) else None,
        "orientation_deg": float(features.orientation_deg),
        "bin_per_mm": [1e-3 / (w * pitch[0]), 1e-3 / (h * pitch[1])],
    }
    if texture_map is not None:
        rows, cols = texture_map.grid
        d["tiles"] = {
            "rows": rows,
            "cols": cols,
            "tile_mm": [texture_map.tile_px * texture_map.pitch_m[0] * 1e3, texture_map.tile_px * texture_map.pitch_m[1] * 1e3],
            "spatial_frequency_per_mm": (texture_map.field("spatial_frequency_per_m") * 1e-3).tolist(),
            "spectral_intensity": texture_map.field("spectral_intensity").tolist(),
        }
    return d
