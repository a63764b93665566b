"""The surface model: a picture as a height field, seen through the stylus tip.

Made once per loaded or uploaded picture (docs/surfaces.md, "What is rendered").
The picture's luminance is read as height (bright high, in units of the luminance
range, 0 .. 1); that reading fails on printed patterns, cast shadows and
highlights (docs/references.md, section 3 (luminance as height)).  The tip is a
Gaussian low-pass of standard deviation half its radius (docs/references.md,
section 3 (stylus tip)), applied once here, so a profile along any path is a
bilinear lookup.

Two scales are kept apart: the *display* pitch (metres per pixel where the
picture is shown, what the pen's positions are measured in) and the *surface*
pitch (metres per pixel of the real surface, which the tip radius is measured
in).  They are equal unless the picture's real size is given.

A picture can carry its relief in metres (docs/surfaces.md, "Materials"): with a
material or a relief scale (:func:`tactilize.materials.relief_for`) the heights,
prominences and floors are in metres, the contact of a compliant material widens
the tip's low-pass, and the material's micro-roughness is added where the tip is.

Units: SI (metres); heights in luminance units, or metres with a relief.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from scipy.ndimage import map_coordinates

from ..errors import ImageError, check_finite
from ..materials.relief import relief_for

__all__ = ["SurfaceLike", "SurfaceModel", "surface_model", "TIP_RADIUS_M", "PROMINENCE_FLOOR", "PROMINENCE_SHARE_OF_STD"]

#: Default stylus tip radius [m]: docs/references.md, section 3 (stylus tip).
TIP_RADIUS_M = 0.25e-3
#: Least prominence of a bump [luminance units]: five grey levels of eight-bit,
#: above the noise of a JPEG.
PROMINENCE_FLOOR = 0.02
#: ...or this share of the tip-filtered height's standard deviation, when larger:
#: a picture's own texture, not its grain noise, makes its bumps.
PROMINENCE_SHARE_OF_STD = 0.2
#: Pixels used to estimate the standard deviation, at most (a strided subsample).
_STD_SAMPLE_PX = 1 << 18


class SurfaceLike(Protocol):
    """What every consumer reads of a surface: one picture (:class:`SurfaceModel`) or several
    side by side (:class:`~tactilize.surface.composite.CompositeSurface`)."""

    @property
    def step_m(self) -> float:
        """Spacing [display m] at which a profile along a path is sampled."""
        ...

    @property
    def tip_radius_m(self) -> float:
        """The stylus tip's radius [m on the real surface]."""
        ...

    @property
    def surface_per_display(self) -> float:
        """Real surface metres per display metre."""
        ...

    @property
    def width_m(self) -> float:
        """Width where shown [display m]."""
        ...

    @property
    def height_m(self) -> float:
        """Height where shown [display m]."""
        ...

    def regions(self, x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(heights, region ids (-1 off every picture), prominence floors) at display points [m]."""
        ...


@dataclass(frozen=True, eq=False)
class SurfaceModel:
    """A picture as a tip-filtered height field, addressed by display position.

    Attributes
    ----------
    height : ndarray of float32, shape (rows, cols)
        Tip-filtered height [luminance units, 0 .. 1]; row 0 is the top.
    display_pitch_m : (float, float)
        (x, y) size of a pixel where the picture is shown [m].
    surface_pitch_m : (float, float)
        (x, y) size of a pixel on the real surface [m].
    tip_radius_m : float
        Stylus tip radius on the real surface [m].
    prominence_floor : float
        Least prominence of a bump [luminance units] (:data:`PROMINENCE_FLOOR`
        or :data:`PROMINENCE_SHARE_OF_STD` of the height's deviation).
    raw : ndarray of float32
        The unfiltered height, kept for :meth:`at_scale` [luminance units].
    relief : Relief or None
        The relief in metres and its material (:class:`tactilize.materials.Relief`); None for
        the picture alone (heights in luminance units).
    micro : MicroRoughness or None
        The material's micro-roughness as the tip follows it, added to every lookup.
    """

    height: np.ndarray
    display_pitch_m: tuple[float, float]
    surface_pitch_m: tuple[float, float]
    tip_radius_m: float
    prominence_floor: float
    raw: np.ndarray
    relief: Any = None
    micro: Any = None
    # Made in __post_init__ (see there), not parameters.
    _padded: np.ndarray = field(init=False, repr=False, compare=False)
    _inv_pitch: tuple[float, float] = field(init=False, repr=False, compare=False)

    @property
    def shape(self) -> tuple[int, int]:
        rows, cols = self.height.shape
        return int(rows), int(cols)

    @property
    def width_m(self) -> float:
        """Displayed width [m]."""
        return self.shape[1] * self.display_pitch_m[0]

    @property
    def height_m(self) -> float:
        """Displayed height [m]."""
        return self.shape[0] * self.display_pitch_m[1]

    @property
    def surface_per_display(self) -> float:
        """Metres of real surface per metre of display (1 unless a real scale was given)."""
        return self.surface_pitch_m[0] / self.display_pitch_m[0]

    @property
    def full_prominence(self) -> float | None:
        """Prominence of full strength [m] on a surface in metres; None for the picture alone
        (:data:`tactilize.surface.events.FULL_PROMINENCE`)."""
        from ..materials.relief import FULL_PROMINENCE_M

        return None if self.relief is None else FULL_PROMINENCE_M

    @property
    def full_scale_acceleration(self) -> float | None:
        """Acceleration [m/s^2] at an output's full scale on a surface in metres; None for the
        picture alone (:data:`tactilize.synthesis.acceleration.FULL_SCALE_ACCELERATION`)."""
        from ..materials.relief import FULL_SCALE_ACCELERATION_M_S2

        return None if self.relief is None else FULL_SCALE_ACCELERATION_M_S2

    def micro_at(self, x_m: Any, y_m: Any) -> np.ndarray | float:
        """The micro-roughness [m] at display positions [m] (0 without a material): drawn on
        the real surface, so the same spot gives the same height every time."""
        if self.micro is None:
            return 0.0
        sx, sy = (self.surface_pitch_m[i] / self.display_pitch_m[i] for i in (0, 1))
        return self.micro.height_m(np.asarray(x_m, dtype=np.float64) * sx, np.asarray(y_m, dtype=np.float64) * sy)

    @property
    def step_m(self) -> float:
        """Spacing [display m] at which a profile along a path is sampled: a quarter
        of the tip radius, and never coarser than half a pixel."""
        return min(0.25 * self.tip_radius_m / self.surface_per_display, 0.5 * min(self.display_pitch_m))

    def __post_init__(self) -> None:
        # Made once per picture: the height with a one-pixel border repeating its edge, so a
        # lookup needs no clamping to the picture.
        object.__setattr__(self, "_padded", np.pad(self.height, 1, mode="edge"))
        object.__setattr__(self, "_inv_pitch", (1.0 / self.display_pitch_m[0], 1.0 / self.display_pitch_m[1]))

    def sample(self, x_m: np.ndarray, y_m: np.ndarray) -> np.ndarray:
        """Tip-filtered height at display positions [m] (from the top-left, y down),
        bilinear between pixel centres; NaN outside the picture."""
        h, inside = self._lookup(x_m, y_m)
        return h if inside is None else np.where(inside, h, np.nan)

    def _lookup(self, x_m: Any, y_m: Any) -> tuple[np.ndarray, np.ndarray | None]:
        """(bilinear height, inside) at display positions; outside, the height is the nearest
        edge's; inside is None when every point is on the picture (the usual case)."""
        rows, cols = self.shape
        # Pixel coordinates; in the padded picture pixel centres are at 1 .. cols.
        x = np.asarray(x_m, dtype=np.float64) * self._inv_pitch[0]
        y = np.asarray(y_m, dtype=np.float64) * self._inv_pitch[1]
        h = map_coordinates(self._padded, (y + 0.5, x + 0.5), output=np.float64, order=1, mode="nearest",
                            prefilter=False)
        if self.micro is not None:
            h = h + self.micro_at(x_m, y_m)
        if x.size and x.min() >= 0.0 and x.max() < cols and y.min() >= 0.0 and y.max() < rows:
            return h, None
        return h, (x >= 0.0) & (x < cols) & (y >= 0.0) & (y < rows)

    def regions(self, x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(heights, region ids, prominence floors) along points: one region (0) inside, -1 outside.

        :class:`~tactilize.surface.composite.CompositeSurface` answers the same
        with one region per picture, so bumps are never found across a boundary.
        """
        h, inside = self._lookup(x_m, y_m)
        floors = np.full(h.shape, self.prominence_floor)
        if inside is None:  # the usual case: a stroke on the picture
            return h, np.zeros(h.shape, dtype=np.intp), floors
        ids = inside.astype(np.intp) - 1  # 0 inside, -1 outside
        return np.where(inside, h, np.nan), ids, floors

    def at_scale(self, surface_pitch_m: float | tuple[float, float]) -> "SurfaceModel":
        """The same picture as a surface of another real size [m per pixel]."""
        pair = _pair(surface_pitch_m, "surface_pitch_m")
        return _build(self.raw, self.display_pitch_m, pair, self.tip_radius_m, self.relief)

    def at_display_pitch(self, display_pitch_m: float | tuple[float, float]) -> "SurfaceModel":
        """The same surface shown at another size; its real scale follows the display
        unless it was set apart (then it stays)."""
        pair = _pair(display_pitch_m, "display_pitch_m")
        same = self.surface_pitch_m == self.display_pitch_m
        return _build(self.raw, pair, pair if same else self.surface_pitch_m, self.tip_radius_m, self.relief)


def _pair(value: Any, what: str) -> tuple[float, float]:
    pair = (value, value) if np.isscalar(value) else tuple(value)
    if len(pair) != 2:
        raise ImageError(f"<{what}>", "needs one value or an (x, y) pair")
    for v in pair:
        check_finite(v, f"<{what}>", what=what, error=ImageError, above=0.0, unit="m")
    return float(pair[0]), float(pair[1])


def _tip_filter(raw: np.ndarray, sigma_px: tuple[float, float]) -> np.ndarray:
    """The Gaussian low-pass of the tip, by FFT: a third of the time of a direct filter on a
    2048 x 2048 upload (75 against 240 ms here), about three bare rfft2s.  The picture is
    padded by three standard deviations of its own edge values, so nothing wraps around."""
    import scipy.fft
    from scipy.ndimage import fourier_gaussian

    pr, pc = (int(np.ceil(3 * s)) + 1 for s in sigma_px)
    rows, cols = raw.shape
    shape = (scipy.fft.next_fast_len(rows + 2 * pr, real=True), scipy.fft.next_fast_len(cols + 2 * pc, real=True))
    padded = np.pad(raw, ((pr, shape[0] - rows - pr), (pc, shape[1] - cols - pc)), mode="edge")
    spec = scipy.fft.rfft2(padded, workers=1)
    fourier_gaussian(spec, sigma_px, n=shape[1], output=spec)  # in place: stays single precision
    out = scipy.fft.irfft2(spec, s=shape, workers=1)[pr : pr + rows, pc : pc + cols]
    return np.ascontiguousarray(out, dtype=np.float32)


def _build(raw: np.ndarray, display: tuple[float, float], surface: tuple[float, float], tip_m: float,
           relief: Any = None) -> SurfaceModel:
    # With a material the contact's footprint widens the tip's low-pass and a compliant layer
    # gives under the tip (docs/references.md, section 11 (hardness)); the heights are metres.
    sigma_m = 0.5 * tip_m if relief is None else relief.footprint_sigma_m(tip_m)
    sigma_px = (sigma_m / surface[1], sigma_m / surface[0])  # (rows, cols)
    src = raw if relief is None else raw * np.float32(relief.height_scale_m(tip_m))
    height = _tip_filter(src, sigma_px) if max(sigma_px) > 0.05 else src
    sample = height.ravel()[:: max(1, height.size // _STD_SAMPLE_PX)]
    if relief is None:
        floor = max(PROMINENCE_FLOOR, PROMINENCE_SHARE_OF_STD * float(np.std(sample)))
        return SurfaceModel(height, display, surface, float(tip_m), floor, raw)
    floor = relief.prominence_floor_m(float(np.std(sample)))
    return SurfaceModel(height, display, surface, float(tip_m), floor, raw, relief, relief.micro(tip_m))


def surface_model(
    image: Any,
    *,
    tip_radius_m: float = TIP_RADIUS_M,
    surface_pitch_m: float | tuple[float, float] | None = None,
    pitch_m: float | tuple[float, float] | None = None,
    material: Any = None,
    relief_scale_m: float | str | None = None,
    relief_rms_m: float | None = None,
) -> SurfaceModel:
    """The surface model of a picture (or of a height array).

    Parameters
    ----------
    image : TextureImage or array_like
        A loaded picture (its luminance is the height) or a 2-D array of heights
        in luminance units (give ``pitch_m``).
    tip_radius_m : float
        Stylus tip radius on the real surface [m].
    surface_pitch_m : float or (float, float), optional
        Real size of a pixel of the surface [m]; the display pitch by default.
    pitch_m : float or (float, float), optional
        Display pitch [m] of an array (a TextureImage carries its own).
    material : str or Material, optional
        A library material (docs/surfaces.md, "Materials"): heights in metres at its typical
        relief, its hardness and micro-roughness.  None: the picture alone, as before.
    relief_scale_m : float or "estimate", optional
        Metres of relief per unit of luminance (given), or ``"estimate"``; with a material
        it replaces the material's typical relief.
    relief_rms_m : float, optional
        RMS height of the picture's visible relief [m] (its luminance less what varies
        slower than 5 mm), given: with a material it replaces the material's typical
        relief.  Not with ``relief_scale_m``.

    Returns
    -------
    SurfaceModel

    Raises
    ------
    ImageError
        Not a 2-D array of finite heights, or a pitch or tip that is not positive.
    MaterialError
        An unknown material, or a relief scale or RMS that is not a positive number.
    """
    check_finite(tip_radius_m, "<tip_radius_m>", what="tip radius", error=ImageError, above=0.0, unit="m")
    if hasattr(image, "pixels") and hasattr(image, "pitch_m"):
        raw = np.asarray(image.pixels, dtype=np.float32)
        display = _pair(image.pitch_m if pitch_m is None else pitch_m, "pitch_m")
        source = getattr(image, "source", "<image>")
    else:
        if pitch_m is None:
            raise ImageError("<array>", "a height array needs pitch_m (metres per pixel)")
        raw = np.asarray(image, dtype=np.float32)
        display = _pair(pitch_m, "pitch_m")
        source = "<array>"
    if raw.ndim != 2 or min(raw.shape) < 1:
        raise ImageError(source, f"a height field must be a 2-D array, got shape {raw.shape}")
    if not np.isfinite(raw).all():
        raise ImageError(source, "heights must be finite numbers")
    surface = display if surface_pitch_m is None else _pair(surface_pitch_m, "surface_pitch_m")
    if not math.isfinite(tip_radius_m):
        raise ImageError("<tip_radius_m>", "not finite")
    relief = relief_for(raw, surface, material, relief_scale_m, relief_rms_m)
    return _build(raw, display, surface, float(tip_radius_m), relief)
