"""Built-in texture pictures, generated deterministically with numpy.

Sample data to try tactilize on, as ``skimage.data`` is for scikit-image.
Seven pictures that span the range of the paper's images (docs/references.md,
section 1: f_s from about 265 to 4217 cycles/m, i_s from 0.21 to 0.93): fine to
coarse, strongly to weakly periodic, oriented and isotropic, and one whose
texture changes across the picture.  Each is generated from a fixed seed, so the
pixels (and therefore the features) are identical on every machine and run;
nothing is downloaded and no licence question arises.

Every picture carries its physical size: it is rendered at :data:`TEXTURE_DPI`
so that the page can show it at the size the features were measured for.

>>> from tactilize.data import builtin_textures
>>> [t.id for t in builtin_textures()]  # doctest: +NORMALIZE_WHITESPACE
['corduroy', 'linen', 'canvas', 'dots', 'wood', 'sandpaper', 'patchwork']
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from typing import Any, Callable

import numpy as np

from .image import TextureImage, load_image

__all__ = ["BuiltinTexture", "builtin_textures", "builtin_map", "get_texture", "texture_ids", "TEXTURE_DPI", "TEXTURE_SIZE_PX", "png_bytes"]

#: Pixels per inch of the built-in pictures.  300 dpi (pitch 84.7 um) leaves room
#: below Nyquist (5.9 cycles/mm) for the paper's finest texture (4.2 cycles/mm).
TEXTURE_DPI = 300.0
#: (width, height) [px]: 67.7 x 50.8 mm at 300 dpi, a palm-sized swatch.
TEXTURE_SIZE_PX = (800, 600)

_PITCH_M = 0.0254 / TEXTURE_DPI


@dataclass(frozen=True, eq=False)
class BuiltinTexture:
    """One built-in picture.

    Attributes
    ----------
    id : str
        Short stable name (URL-safe).
    name : str
        Human name.
    description : str
        What it is and which part of the paper's range it covers.
    make : callable
        ``make(xx_m, yy_m, rng) -> ndarray`` grey levels in [0, 1] over the
        pixel-centre coordinates [m] (y down).
    seed : int
        Seed of the generator the picture uses.
    """

    id: str
    name: str
    description: str
    make: Callable[[np.ndarray, np.ndarray, np.random.Generator], np.ndarray] = field(repr=False)
    seed: int = 0

    @cached_property
    def image(self) -> TextureImage:
        """The picture as a :class:`~tactilize.image.TextureImage` (8-bit grey levels, 300 dpi)."""
        # The 8-bit pixels, exactly as the page shows them, so the features match the PNG.
        return load_image(self.pixels_u8, dpi=TEXTURE_DPI).with_source(f"builtin:{self.id}")

    @cached_property
    def pixels_u8(self) -> np.ndarray:
        """The picture as 8-bit grey levels, shape (height, width); what the page shows."""
        w, h = TEXTURE_SIZE_PX
        xs = (np.arange(w) + 0.5) * _PITCH_M
        ys = (np.arange(h) + 0.5) * _PITCH_M
        xx, yy = np.meshgrid(xs, ys)
        grey = np.clip(self.make(xx, yy, np.random.default_rng(self.seed)), 0.0, 1.0)
        out = np.round(grey * 255.0).astype(np.uint8)
        out.setflags(write=False)
        return out

    @property
    def width_m(self) -> float:
        """Displayed width [m]."""
        return TEXTURE_SIZE_PX[0] * _PITCH_M

    @property
    def height_m(self) -> float:
        """Displayed height [m]."""
        return TEXTURE_SIZE_PX[1] * _PITCH_M

    @cached_property
    def png(self) -> bytes:
        """The picture as a PNG file carrying its DPI."""
        return png_bytes(self.pixels_u8, TEXTURE_DPI)

    def describe(self) -> dict[str, Any]:
        """Plain summary for listings (sizes in px and mm)."""
        return {
            "id": self.id,
            "name": self.name,
            "description": self.description,
            "width_px": TEXTURE_SIZE_PX[0],
            "height_px": TEXTURE_SIZE_PX[1],
            "width_mm": self.width_m * 1e3,
            "height_mm": self.height_m * 1e3,
            "dpi": TEXTURE_DPI,
        }


def png_bytes(pixels_u8: np.ndarray, dpi: float) -> bytes:
    """Encode 8-bit grey pixels as PNG with its DPI stored (pHYs)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(pixels_u8), mode="L").save(buf, format="PNG", dpi=(dpi, dpi), optimize=False)
    return buf.getvalue()


# ----------------------------------------------------------------- generators
# Wavelengths are chosen against the paper's Table 1/2 (f_s in cycles/m) and
# each says which of the paper's images it stands in for.


def _grating(xx: np.ndarray, yy: np.ndarray, wavelength_m: float, angle_deg: float) -> np.ndarray:
    """cos of a plane wave; angle of the wave vector CCW from +x with y up."""
    a = math.radians(angle_deg)
    # yy points down the picture; the y-up component of position is -yy.
    return np.cos(2 * np.pi * (xx * math.cos(a) - yy * math.sin(a)) / wavelength_m)


def _smooth_noise(shape: tuple[int, int], rng: np.random.Generator, corr_px: float) -> np.ndarray:
    """Gaussian-filtered white noise scaled to unit standard deviation."""
    from scipy.ndimage import gaussian_filter

    n = gaussian_filter(rng.standard_normal(shape), corr_px, mode="wrap")
    return n / (n.std() or 1.0)


def _corduroy(xx, yy, rng):
    # Coarse ribs, 3.6 mm: f_s ~ 280 /m like the paper's coarsest images (265, 287).
    ribs = 0.5 + 0.42 * np.sign(_grating(xx, yy, 3.6e-3, 0.0)) * np.abs(_grating(xx, yy, 3.6e-3, 0.0)) ** 0.5
    return ribs + 0.04 * rng.standard_normal(xx.shape)


def _linen(xx, yy, rng):
    # Medium diagonal weave, 1.25 mm at 45 deg: f_s ~ 800 /m like the paper's image 1 (799).
    return 0.5 + 0.35 * _grating(xx, yy, 1.25e-3, 45.0) + 0.06 * rng.standard_normal(xx.shape)


def _canvas(xx, yy, rng):
    # Fine plain weave, 0.24 mm threads crossing at 0 and 90 deg: f_s ~ 4200 /m
    # like the paper's finest image (4217), weakly periodic under strong noise.
    weave = 0.5 + 0.12 * _grating(xx, yy, 0.24e-3, 0.0) * (0.6 + 0.4 * _grating(xx, yy, 0.48e-3, 90.0))
    return weave + 0.12 * _smooth_noise(xx.shape, rng, 1.0)


def _dots(xx, yy, rng):
    # Hexagonal lattice of round bumps, 1.8 mm apart: isotropic yet periodic
    # (three equal peaks 60 deg apart), f_s ~ 640 /m (between 563 and 799).
    d = 1.8e-3
    k = 2 * np.pi / (d * math.sqrt(3) / 2)
    s = sum(np.cos(k * (xx * math.cos(a) - yy * math.sin(a))) for a in (0.0, math.pi / 3, 2 * math.pi / 3))
    bumps = 1.0 / (1.0 + np.exp(-2.5 * (s - 1.0)))
    return 0.2 + 0.6 * bumps + 0.03 * rng.standard_normal(xx.shape)


def _wood(xx, yy, rng):
    # Wavy grain near 2.3 mm, running diagonally at 120 deg: oriented, but the
    # period wanders, so the peak is broad (weak periodicity); f_s ~ 430 /m (443).
    warp = 1.2e-3 * _smooth_noise(xx.shape, rng, 40.0)
    a = math.radians(120.0)
    phase = 2 * np.pi * ((xx * math.cos(a) - yy * math.sin(a)) + warp) / 2.3e-3
    return 0.55 + 0.3 * np.cos(phase) + 0.08 * _smooth_noise(xx.shape, rng, 1.5)


def _sandpaper(xx, yy, rng):
    # Isotropic grit with no period: the weak end of i_s (the paper's 0.213 image).
    grit = _smooth_noise(xx.shape, rng, 0.8)
    return 0.5 + 0.12 * grit


def _patchwork(xx, yy, rng):
    # Four fabrics in the quadrants: coarse vertical ribs (top left), a fine
    # horizontal grating (top right), medium diagonal (bottom left) and grit
    # (bottom right).  The texture map must change under the pen.
    w, h = TEXTURE_SIZE_PX[0] * _PITCH_M, TEXTURE_SIZE_PX[1] * _PITCH_M
    right, bottom = xx >= w / 2, yy >= h / 2
    out = np.where(
        ~bottom,
        np.where(~right, 0.5 + 0.4 * _grating(xx, yy, 3.0e-3, 0.0), 0.5 + 0.35 * _grating(xx, yy, 0.5e-3, 90.0)),
        np.where(~right, 0.5 + 0.35 * _grating(xx, yy, 1.2e-3, 135.0), 0.5 + 0.12 * _smooth_noise(xx.shape, rng, 0.8)),
    )
    return out


_BUILTINS: tuple[BuiltinTexture, ...] = (
    BuiltinTexture("corduroy", "Corduroy", "Coarse vertical ribs, 3.6 mm: coarse, strongly periodic, oriented.", _corduroy, 1),
    BuiltinTexture("linen", "Linen", "Diagonal weave, 1.25 mm at 45 deg: medium, periodic, oriented.", _linen, 2),
    BuiltinTexture("canvas", "Fine canvas", "Fine weave, 0.24 mm threads under noise: fine, weakly periodic.", _canvas, 3),
    BuiltinTexture("dots", "Dot lattice", "Hexagonal bumps 1.8 mm apart: periodic but isotropic.", _dots, 4),
    BuiltinTexture("wood", "Wood grain", "Wavy grain near 2.3 mm: oriented, weakly periodic.", _wood, 5),
    BuiltinTexture("sandpaper", "Sandpaper", "Fine isotropic grit: no period at all.", _sandpaper, 6),
    BuiltinTexture(
        "patchwork",
        "Patchwork",
        "Four fabrics in the quadrants (ribs, fine stripes, diagonal, grit): the texture changes under the pen.",
        _patchwork,
        7,
    ),
)


def builtin_textures() -> tuple[BuiltinTexture, ...]:
    """All built-in textures, in gallery order (pictures are generated on first use)."""
    return _BUILTINS


def texture_ids() -> list[str]:
    """The ids of the built-in textures."""
    return [t.id for t in _BUILTINS]


def get_texture(texture_id: str) -> BuiltinTexture:
    """One built-in texture by id.

    Raises
    ------
    KeyError
        No built-in texture has that id.
    """
    for t in _BUILTINS:
        if t.id == texture_id:
            return t
    raise KeyError(texture_id)


@lru_cache(maxsize=None)
def builtin_map(texture_id: str):
    """The :class:`~tactilize.maps.texturemap.TextureMap` of a built-in texture (cached)."""
    from .maps.texturemap import texture_map

    return texture_map(get_texture(texture_id).image)
