"""Stand-in pictures for protocol images that give features but no file.

The paper's pictures are not distributed with its text; its tables give their
features.  The built-in protocols therefore drive with the tables' numbers and
show a rendered texture whose period is the stated spatial frequency, at a known
pitch, so that what the participant sees and what they feel agree in scale.
"""

from __future__ import annotations

import functools
import io
import math

import numpy as np

from .design import ImageSpec

__all__ = ["PITCH_M", "SIZE_PX", "render_png", "render_array"]

# Rendered at 0.1 mm per pixel: the finest paper image (4217 /m, 0.24 mm) still has
# more than two pixels per period, and the page scales the picture to true size
# with the calibrated mm per CSS pixel.
PITCH_M = 1e-4
SIZE_PX = (400, 600)  # 40 x 60 mm


def render_array(spec, size_px: tuple[int, int] = SIZE_PX, seed: int = 0) -> np.ndarray:
    """Grey levels in [0, 1], shape ``size_px`` (rows, columns), at :data:`PITCH_M`.

    Parameters
    ----------
    spec : ImageSpec
        ``texture``, ``spatial_frequency_per_m``, ``spectral_intensity`` and
        ``orientation_deg`` are used; the spectral intensity sets the contrast,
        since a stronger spectral peak is a more pronounced periodic pattern.
    """
    h, w = size_px
    y, x = np.mgrid[0:h, 0:w].astype(np.float64) * PITCH_M
    y = -y  # orientation is counter-clockwise with y up, as in the features
    k = 2 * math.pi * spec.spatial_frequency_per_m
    th = math.radians(spec.orientation_deg)
    u = x * math.cos(th) + y * math.sin(th)
    v = -x * math.sin(th) + y * math.cos(th)
    contrast = 0.15 + 0.85 * float(spec.spectral_intensity)
    rng = np.random.default_rng(seed)
    if spec.texture == "grating":
        z = np.cos(k * u)
    elif spec.texture == "weave":
        z = np.sign(np.cos(k * u / 2)) * np.cos(k * v) * 0.5 + np.cos(k * u) * 0.5
    elif spec.texture == "dots":
        z = np.cos(k * u) * np.cos(k * v)
        z = np.where(z > 0.3, 1.0, -1.0) * 0.8 + 0.2 * np.cos(k * u)
    else:  # noise with a grain of about one period
        from scipy.ndimage import gaussian_filter

        grain_px = max(0.6, 1.0 / (spec.spatial_frequency_per_m * PITCH_M) / 4)
        z = gaussian_filter(rng.standard_normal((h, w)), grain_px)
        z = z / (np.abs(z).max() or 1.0)
    z = z + 0.08 * rng.standard_normal((h, w))  # a little grain keeps it from looking synthetic
    return np.clip(0.5 + 0.5 * contrast * z, 0.0, 1.0)


@functools.lru_cache(maxsize=64)
def _png_cached(key: tuple) -> bytes:
    from PIL import Image

    spec = ImageSpec(**dict(key))
    arr = render_array(spec)
    im = Image.fromarray((arr * 255).astype(np.uint8), mode="L")
    buf = io.BytesIO()
    # Record the pitch in the file: 0.1 mm/px = 254 DPI, so tactilize's loader
    # measures the same features from the PNG as the protocol states.
    im.save(buf, format="PNG", dpi=(0.0254 / PITCH_M, 0.0254 / PITCH_M))
    return buf.getvalue()


def render_png(spec) -> bytes:
    """The PNG of a protocol image (rendered stand-in, or the file converted)."""
    if spec.path:
        from PIL import Image

        with Image.open(spec.path) as im:
            buf = io.BytesIO()
            im.convert("L").save(buf, format="PNG")
            return buf.getvalue()
    return _png_cached(tuple(sorted(spec.to_dict().items())))
