"""Loading texture images: files, bytes, file objects or arrays -> :class:`TextureImage`.

A texture image is a grey float32 array in [0, 1] plus the physical size of a
pixel on the display [m].  The pitch comes, in order, from an explicit ``dpi``,
an explicit ``width_mm``, the file's own DPI metadata, and otherwise 96 DPI
(a CSS pixel, 1/96 inch).  That rule is written once, in :func:`_display_pitch`,
and holds for a JPEG decoded at reduced size too (``load_image(draft_pitch_m=...)``).
"""

from __future__ import annotations

import io
import os
import struct
import warnings
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from .errors import ImageError, path_fault, special_file_fault

__all__ = ["DEFAULT_DPI", "DEFAULT_MAX_PIXELS", "DRAFT_MIN_SIDE_PX", "METRES_PER_INCH", "TextureImage", "load_image"]

METRES_PER_INCH = 0.0254
#: a CSS pixel is 1/96 inch by definition: docs/references.md, section 5 (CSS pixel)
DEFAULT_DPI = 96.0
#: Plausible displayed pixel pitch [m]: 0.1 um (254 000 DPI, beyond any print) .. 1 m
#: per pixel.  Outside it the frequencies overflow or divide by zero downstream.
PITCH_RANGE_M = (1e-7, 1.0)
#: 64 Mpx: a 8192 x 8192 texture still loads; a decompression bomb does not.
#: As float32 that is 256 MB, the most one image may cost.
DEFAULT_MAX_PIXELS = 64 * 1024 * 1024

#: Shortest side a reduced JPEG decode may leave [px]: below this the spectrum has
#: too few bins to find a texture's peak in.
DRAFT_MIN_SIDE_PX = 16

# ITU-R BT.601 luma, what Pillow's "L" conversion uses; kept here for float modes.
_LUMA = np.array([0.299, 0.587, 0.114], dtype=np.float32)


class TextureImage:
    """A grey texture image with its physical pixel pitch.

    Attributes
    ----------
    pixels : ndarray of float32, shape (height, width)
        Grey levels in [0, 1], 0 black.  Row 0 is the top of the picture.
        An image decoded from 8-bit data keeps its 8-bit levels and makes this
        array on first use (then keeps it): the analysis reads the levels
        directly, a quarter of the memory traffic and no conversion pass.
    pitch_m : tuple of float
        (x, y) size of one pixel on the display [m].
    source : str
        Where it came from (a path, ``<bytes>``, ``<array>``...), for messages.
    decode_scale : int
        1, or 2, 4 or 8 when a JPEG was decoded at that fraction of its size
        (:func:`load_image` with ``draft_pitch_m``): each pixel then covers
        that many file pixels a side, and :attr:`pitch_m` is that much larger.

    Immutable; equal only to itself.
    """

    __slots__ = ("_levels", "_pixels", "decode_scale", "pitch_m", "source")

    _levels: np.ndarray | None
    _pixels: np.ndarray | None
    pitch_m: tuple[float, float]
    source: str
    decode_scale: int

    def __init__(
        self, pixels: np.ndarray, pitch_m: tuple[float, float], source: str = "<array>", decode_scale: int = 1
    ) -> None:
        _set_fields(self, None, pixels, pitch_m, source, decode_scale)

    @classmethod
    def from_levels(
        cls, levels: np.ndarray, pitch_m: tuple[float, float], source: str = "<array>", decode_scale: int = 1
    ) -> TextureImage:
        """An image from 8-bit grey levels (uint8, 0 black, 255 white), converted lazily."""
        if levels.dtype != np.uint8 or levels.ndim != 2:
            raise TypeError(f"levels must be a 2-D uint8 array, got {levels.dtype} {levels.shape}")
        img = cls.__new__(cls)
        _set_fields(img, levels, None, pitch_m, source, decode_scale)
        return img

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"TextureImage is immutable (cannot set {name!r})")

    def __repr__(self) -> str:
        h, w = self.shape
        return f"TextureImage({w} x {h} px, pitch_m={self.pitch_m!r}, source={self.source!r})"

    def __reduce__(self) -> tuple[Any, ...]:
        if self._levels is not None:
            return (TextureImage.from_levels, (self._levels, self.pitch_m, self.source, self.decode_scale))
        return (TextureImage, (self._pixels, self.pitch_m, self.source, self.decode_scale))

    @property
    def pixels(self) -> np.ndarray:
        """Grey levels in [0, 1], float32 (H, W)."""
        if self._pixels is None:
            # The same division the loader always used: identical values to a float decode.
            pixels = self._levels.astype(np.float32) / np.float32(255.0)  # type: ignore[union-attr]
            object.__setattr__(self, "_pixels", pixels)
        return self._pixels  # type: ignore[return-value]

    def analysis_data(self) -> tuple[np.ndarray, float]:
        """(array, scale) such that array * scale is :attr:`pixels`: the 8-bit
        levels with 1/255 when the image has them, else the pixels with 1."""
        if self._levels is not None:
            return self._levels, 1.0 / 255.0
        return self._pixels, 1.0  # type: ignore[return-value]

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) in pixels."""
        return (self._levels if self._levels is not None else self._pixels).shape  # type: ignore[union-attr]

    @property
    def width_m(self) -> float:
        """Displayed width [m]."""
        return self.shape[1] * self.pitch_m[0]

    @property
    def height_m(self) -> float:
        """Displayed height [m]."""
        return self.shape[0] * self.pitch_m[1]

    @property
    def dpi(self) -> tuple[float, float]:
        """(x, y) pixels per inch."""
        return (METRES_PER_INCH / self.pitch_m[0], METRES_PER_INCH / self.pitch_m[1])

    def with_source(self, source: str) -> TextureImage:
        """The same image under another name (for messages)."""
        if self._levels is not None:
            return TextureImage.from_levels(self._levels, self.pitch_m, source, self.decode_scale)
        return TextureImage(self._pixels, self.pitch_m, source, self.decode_scale)  # type: ignore[arg-type]

    def with_pitch(self, pitch_m: float | tuple[float, float]) -> TextureImage:
        """The same pixels shown at another pixel pitch [m]."""
        px, py = _pitch_pair(pitch_m, self.source)
        if self._levels is not None:
            return TextureImage.from_levels(self._levels, (px, py), self.source, self.decode_scale)
        return TextureImage(self._pixels, (px, py), self.source, self.decode_scale)  # type: ignore[arg-type]

    def describe(self) -> dict[str, Any]:
        """Plain summary for reports: pixel size, physical size in mm, dpi."""
        return {
            "width_px": int(self.shape[1]),
            "height_px": int(self.shape[0]),
            "width_mm": self.width_m * 1e3,
            "height_mm": self.height_m * 1e3,
            "dpi": self.dpi[0],
        }


def _set_fields(
    img: TextureImage,
    levels: np.ndarray | None,
    pixels: np.ndarray | None,
    pitch_m: tuple[float, float],
    source: str,
    decode_scale: int,
) -> None:
    # The class refuses setattr to stay immutable; its own constructors go around that.
    for name, value in (
        ("_levels", levels),
        ("_pixels", pixels),
        ("pitch_m", tuple(pitch_m)),
        ("source", source),
        ("decode_scale", int(decode_scale)),
    ):
        object.__setattr__(img, name, value)


def pitch_pair(pitch_m: float | tuple[float, float]) -> tuple[float, float]:
    """(x, y) pixel pitch [m] from one pitch (square pixels) or an (x, y) pair, unchecked."""
    if isinstance(pitch_m, (tuple, list, np.ndarray)):
        px, py = pitch_m
        return px, py
    return pitch_m, pitch_m


def _pitch_pair(pitch_m: float | tuple[float, float], source: str) -> tuple[float, float]:
    px, py = pitch_pair(pitch_m)
    for p in (px, py):
        if not np.isfinite(p) or p <= 0:
            raise ImageError(source, f"pixel pitch must be a positive number of metres, got {p!r}")
    return float(px), float(py)


def load_image(
    source: str | os.PathLike | bytes | bytearray | BinaryIO | np.ndarray | TextureImage,
    *,
    dpi: float | None = None,
    width_mm: float | None = None,
    max_pixels: int = DEFAULT_MAX_PIXELS,
    draft_pitch_m: float | None = None,
) -> TextureImage:
    """Load a texture image as grey float32 in [0, 1] with its pixel pitch.

    Parameters
    ----------
    source : path, bytes, binary file object, ndarray or TextureImage
        Any image Pillow reads (modes 1, L, LA, P, RGB, RGBA, CMYK, I;16, I, F...),
        or an array of shape (H, W), (H, W, 3) or (H, W, 4).  Integer arrays are
        scaled by their dtype's maximum; float arrays must already be in [0, 1].
    dpi : float, optional
        Displayed pixels per inch; overrides everything else.
    width_mm : float, optional
        Displayed width of the whole image [mm] (square pixels).
    max_pixels : int
        Refuse images with more pixels than this (decompression bombs).
    draft_pitch_m : float, optional
        Coarsest displayed pixel pitch [m] the caller needs (``0.0254 / 150``
        for 150 DPI).  A JPEG whose displayed pitch is at least 2, 4 or 8 times
        finer is decoded at 1/2, 1/4 or 1/8 of its size, in the DCT domain
        (Pillow's draft mode), keeping at least :data:`DRAFT_MIN_SIDE_PX`
        pixels on its short side.  The picture keeps its displayed size, so
        the pitch grows by the same factor (:attr:`TextureImage.decode_scale`).
        Other formats decode in full.  None: every image decodes in full.

    Returns
    -------
    TextureImage

    Raises
    ------
    ImageError
        Unreadable or not an image, truncated, empty, too large, non-finite
        values, or a non-positive ``dpi`` / ``width_mm`` / ``draft_pitch_m``.

    Notes
    -----
    EXIF orientation is applied, transparency is composited over white and only
    the first frame of an animation is used.  A reduced decode averages away the
    detail finer than its pixels (libjpeg's DCT scaling is a low-pass filter):
    frequencies below the new Nyquist limit keep their place, contrast and the
    spectral intensity fall (``docs/batch.md``).
    """
    name = _source_name(source)
    for key, value in (("dpi", dpi), ("width_mm", width_mm), ("draft_pitch_m", draft_pitch_m)):
        if value is not None and (not _finite(value) or value <= 0):
            raise ImageError(name, f"{key} must be a positive number, got {value!r}")

    decode_scale = 1
    if isinstance(source, TextureImage):
        data, file_dpi, full_width = source.analysis_data()[0], source.dpi[0], None
        decode_scale = source.decode_scale
    elif isinstance(source, np.ndarray):
        data, file_dpi, full_width = _from_array(source, name, max_pixels), None, None
    else:
        data, file_dpi, full_width = _from_pillow(source, name, max_pixels, dpi, width_mm, draft_pitch_m)

    width = data.shape[1]
    if full_width is None or full_width == width:
        pitch = _display_pitch(width, file_dpi, dpi, width_mm)
    else:
        # Decoded reduced: the rule applies to the picture as the file holds it,
        # and the picture keeps its displayed size with fewer, larger pixels.
        pitch = _display_pitch(full_width, file_dpi, dpi, width_mm) * full_width / width
        decode_scale = round(full_width / width)
    lo, hi = PITCH_RANGE_M
    if not lo <= pitch <= hi:
        given = f"dpi {dpi:g}" if dpi is not None else f"width_mm {width_mm:g}" if width_mm is not None else "its DPI"
        raise ImageError(name, f"{given} gives a pixel {pitch:.3g} m wide; a displayed pixel must be "
                         f"{lo * 1e6:g} um .. {hi:g} m")
    if data.dtype == np.uint8:
        return TextureImage.from_levels(data, (pitch, pitch), name, decode_scale)
    return TextureImage(data, (pitch, pitch), name, decode_scale)


def _display_pitch(width_px: int, file_dpi: float | None, dpi: float | None, width_mm: float | None) -> float:
    """Displayed pixel pitch [m] of a picture ``width_px`` pixels wide.

    The one copy of the rule: an explicit ``dpi``, else an explicit ``width_mm``
    (the whole picture's width [mm]), else the file's DPI metadata, else 96 DPI.
    """
    if dpi is not None:
        return METRES_PER_INCH / dpi
    if width_mm is not None:
        return width_mm * 1e-3 / width_px
    if file_dpi is not None:
        return METRES_PER_INCH / file_dpi
    return METRES_PER_INCH / DEFAULT_DPI


def _draft_scale(pitch_m: float, draft_pitch_m: float, short_side_px: int) -> int:
    """Largest reduction, 1, 2, 4 or 8, that keeps the pitch [m] at or below ``draft_pitch_m``."""
    scale = 1
    # libjpeg scales by 1/2, 1/4 and 1/8 only.  The 1e-9 lets a pitch that is exactly
    # half the target (300 DPI shown, 150 asked) through despite rounding.
    while (
        scale < 8
        and pitch_m * scale * 2 <= draft_pitch_m * (1 + 1e-9)
        and short_side_px // (scale * 2) >= DRAFT_MIN_SIDE_PX
    ):
        scale *= 2
    return scale


def _finite(x: Any) -> bool:
    try:
        return bool(np.isfinite(float(x)))
    except (TypeError, ValueError):
        return False


def _source_name(source: Any) -> str:
    if isinstance(source, (str, os.PathLike)):
        return os.fspath(source)
    if isinstance(source, (bytes, bytearray)):
        return "<bytes>"
    if isinstance(source, np.ndarray):
        return "<array>"
    if isinstance(source, TextureImage):
        return source.source
    return str(getattr(source, "name", "<file>"))


def _check_size(h: int, w: int, name: str, max_pixels: int) -> None:
    if h == 0 or w == 0:
        raise ImageError(name, f"image is empty ({w} x {h} pixels)")
    if h * w > max_pixels:
        raise ImageError(name, f"image too large ({w} x {h} = {w * h} pixels, limit {max_pixels})")


def _from_array(arr: np.ndarray, name: str, max_pixels: int) -> np.ndarray:
    if arr.ndim == 3 and arr.shape[2] in (1, 3, 4):
        pass
    elif arr.ndim != 2:
        raise ImageError(name, f"array must have shape (H, W), (H, W, 3) or (H, W, 4), got {arr.shape}")
    _check_size(arr.shape[0], arr.shape[1], name, max_pixels)
    if arr.dtype == np.uint8 and arr.ndim == 2:
        return np.array(arr, order="C")  # 8-bit levels, kept as such (a copy: the caller may change theirs)
    if arr.dtype == bool:
        a = arr.astype(np.float32)
    elif np.issubdtype(arr.dtype, np.integer):
        info = np.iinfo(arr.dtype)
        if info.min < 0 and arr.min() < 0:
            raise ImageError(name, "integer array has negative values")
        a = arr.astype(np.float32) / np.float32(info.max)
    elif np.issubdtype(arr.dtype, np.floating):
        a = arr.astype(np.float32, copy=False)
        if not np.isfinite(a).all():
            raise ImageError(name, "array has non-finite values (NaN or infinity)")
        lo, hi = float(a.min()), float(a.max())
        if lo < 0 or hi > 1:
            raise ImageError(name, f"float array must lie in [0, 1], found [{lo:g}, {hi:g}]")
    else:
        raise ImageError(name, f"unsupported array dtype {arr.dtype}")
    if a.ndim == 3:
        if a.shape[2] == 1:
            a = a[:, :, 0]
        elif a.shape[2] == 3:
            a = a @ _LUMA
        else:
            alpha = a[:, :, 3]
            a = (a[:, :, :3] @ _LUMA) * alpha + (1.0 - alpha)  # over white
    return np.ascontiguousarray(a, dtype=np.float32)


def _from_pillow(
    source: Any,
    name: str,
    max_pixels: int,
    dpi: float | None = None,
    width_mm: float | None = None,
    draft_pitch_m: float | None = None,
) -> tuple[np.ndarray, float | None, int | None]:
    """Decode with Pillow: (grey, the file's DPI or None, displayed width of the full-size
    picture [px] when a reduced decode was considered, else None)."""
    from PIL import Image, ImageOps, UnidentifiedImageError

    if isinstance(source, (bytes, bytearray)):
        if len(source) == 0:
            raise ImageError(name, "empty input (0 bytes)")
        fp: Any = io.BytesIO(source)
    elif isinstance(source, (str, os.PathLike)):
        path = Path(source)
        fault = path_fault(path)
        if fault is not None:
            raise ImageError(name, fault)
        if path.is_dir():
            raise ImageError(name, "is a directory, not an image")
        special = special_file_fault(path)
        if special is not None:
            raise ImageError(name, special)
        if path.stat().st_size == 0:
            raise ImageError(name, "empty file (0 bytes)")
        fp = path
    else:
        fp = source
    # Pillow's own bomb guard warns at half its limit and raises at the limit; ours is
    # explicit and configurable, so switch Pillow's off for this call and check size
    # from the header before any pixel is decoded.
    saved = Image.MAX_IMAGE_PIXELS
    try:
        Image.MAX_IMAGE_PIXELS = None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im = Image.open(fp)
            w, h = im.size
            _check_size(h, w, name, max_pixels)
            file_dpi = _file_dpi(im)
            full_width = None
            scale = 1
            if draft_pitch_m is not None and im.format == "JPEG":
                # The displayed width is after EXIF rotation (orientations 5 to 8 swap the axes).
                full_width = h if im.getexif().get(0x0112, 1) in (5, 6, 7, 8) else w
                scale = _draft_scale(_display_pitch(full_width, file_dpi, dpi, width_mm), draft_pitch_m, min(w, h))
            if im.format == "JPEG" and (scale > 1 or im.mode in ("RGB", "YCbCr")):
                # libjpeg hands over its luma plane directly: the same BT.601 weights as
                # convert("L") (identical pixels), without colour conversion or chroma
                # upsampling, about 40 % faster.  Pillow takes one draft request per image,
                # so the size reduction, if any, is asked in the same call.
                im.draft("L", (-(-w // scale), -(-h // scale)))
            im.seek(0)  # first frame of an animation
            im.load()
            # In place: without an orientation tag nothing happens (a new image copies every pixel).
            ImageOps.exif_transpose(im, in_place=True)
            grey = _to_grey(im, name)
    except ImageError:
        raise
    except UnidentifiedImageError:
        raise ImageError(name, "not an image Pillow can read") from None
    except FileNotFoundError:
        raise ImageError(name, "file not found") from None
    except PermissionError:
        raise ImageError(name, "permission denied") from None
    except OSError as exc:
        msg = str(exc)
        fault = "truncated or corrupt image" if ("truncated" in msg or "broken" in msg or "image file" in msg) else f"cannot read ({msg})"
        raise ImageError(name, fault) from None
    except (ValueError, SyntaxError, EOFError, IndexError, TypeError, struct.error) as exc:
        raise ImageError(name, f"corrupt image ({exc.__class__.__name__}: {exc})") from None
    except MemoryError:
        raise ImageError(name, "not enough memory to decode") from None
    finally:
        Image.MAX_IMAGE_PIXELS = saved
    return grey, file_dpi, full_width


def _file_dpi(im: Any) -> float | None:
    info = im.info.get("dpi")
    try:
        if info is not None:
            x = float(info[0])
            # Many writers store 1 or 72 as "unknown"; 1 dpi is certainly not a display.
            if np.isfinite(x) and x > 1:
                return x
    except (TypeError, ValueError, IndexError):
        pass
    return None


def _to_grey(im: Any, name: str) -> np.ndarray:
    """Pillow image of any mode -> grey, alpha over white: uint8 levels for 8-bit
    data (every mode Pillow converts to "L"), else float32 in [0, 1]."""
    from PIL import Image

    mode = im.mode
    if mode == "P":
        im = im.convert("RGBA") if "transparency" in im.info else im.convert("RGB")
        mode = im.mode
    if mode in ("RGBA", "LA", "PA", "RGBa", "La"):
        rgba = im.convert("RGBA")
        white = Image.new("RGBA", rgba.size, (255, 255, 255, 255))
        im = Image.alpha_composite(white, rgba).convert("L")
        mode = "L"
    if mode == "F":
        a = np.asarray(im, dtype=np.float32)
        if not np.isfinite(a).all():
            raise ImageError(name, "float image has non-finite values (NaN or infinity)")
        return _rescale(a)
    if mode in ("I", "I;16", "I;16B", "I;16L", "I;16N"):
        a = np.asarray(im)
        if mode.startswith("I;16"):
            return (a.astype(np.float32) / 65535.0).astype(np.float32)
        return _rescale(a.astype(np.float64)).astype(np.float32)
    if mode == "1":
        return np.asarray(im, dtype=np.float32)
    if mode != "L":
        im = im.convert("L")  # RGB, CMYK, YCbCr, LAB, HSV: Pillow's luma conversion
    return np.asarray(im, dtype=np.uint8)


def _rescale(a: np.ndarray) -> np.ndarray:
    """32-bit images have no fixed white: use [0, 1] if they fit, else their own range."""
    lo, hi = float(a.min()), float(a.max())
    if lo >= 0 and hi <= 1:
        return a.astype(np.float32)
    if hi <= 65535 and lo >= 0:
        return (a / 65535.0).astype(np.float32) if hi > 255 else (a / 255.0).astype(np.float32)
    if hi == lo:
        return np.zeros(a.shape, np.float32)
    return ((a - lo) / (hi - lo)).astype(np.float32)
