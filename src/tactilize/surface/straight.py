"""A steady straight stroke over a picture.

One rule for every steady straight stroke (the commands that take a picture and
a speed: ``drive``, ``simulate``, ``profile report``, the exports' synthetic
strokes, the serial report): the stylus starts at the picture's centre and runs
on in a straight line at that speed, past the edges if the stroke is longer than
the picture; beyond an edge the picture is continued by its mirror image
(:class:`MirroredSurface`, :func:`fold_into`).  A stroke turned back at the edge
would stop and reverse, which a tracker sees as a slow-down at every turn; over
mirror images the speed and direction stay steady however long the stroke.

What a rendering gives such a stroke is :func:`tactilize.surface.rendering.surface_stroke_drive`.

Units: SI (m, s, Hz).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .model import SurfaceLike

__all__ = ["straight_stroke", "fold_into", "MirroredSurface", "STROKE_S", "STROKE_RATE_HZ"]

#: Length of the steady stroke [s].
STROKE_S = 2.0
#: Its sample rate [Hz] (a pen tablet's).
STROKE_RATE_HZ = 240.0
#: Fraction of a picture's size its mirror images are folded at: just inside the
#: far edges, since a lookup takes coordinates in [0, width).
_INSIDE = 1.0 - 1e-9


def straight_stroke(width_m: float, height_m: float, speed_m_s: float, direction_rad: float = 0.0,
                    duration_s: float = STROKE_S, rate_hz: float = STROKE_RATE_HZ,
                    preroll_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples of a steady straight stroke from a picture's centre.

    Parameters
    ----------
    width_m, height_m : float
        The picture's size where shown [m].
    speed_m_s : float
        The stroke's speed [m/s].
    direction_rad : float
        Its direction [rad], counter-clockwise from +x with y up.
    duration_s : float
        How long it lasts after time 0 [s]; the samples run one past it.
    rate_hz : float
        Sample rate [Hz].
    preroll_s : float
        Time [s] the stroke is already moving before time 0 (negative times),
        so that a tracker knows its speed at time 0.  The stylus is at the
        centre at ``-preroll_s``.

    Returns
    -------
    t_s, x_m, y_m : numpy.ndarray
        Times [s] and positions [m] (y down).  The line is not folded: it runs
        past the picture's edges when the stroke is longer than the picture,
        where the picture is read mirrored (:class:`MirroredSurface`, or
        :func:`fold_into` for positions on the picture itself).
    """
    ux, uy = math.cos(direction_rad), -math.sin(direction_rad)  # y down on the picture
    n = int(math.floor((duration_s + preroll_s) * rate_hz)) + 2
    elapsed = np.arange(n) / rate_hz
    travel = speed_m_s * elapsed
    return -preroll_s + elapsed, width_m / 2 + ux * travel, height_m / 2 + uy * travel


def fold_into(v: Any, span_m: float) -> np.ndarray:
    """Positions [m] beyond ``[0, span_m]`` reflected back into it, as the mirror images
    of a picture of that size continue it (an empty span leaves them as they are)."""
    v = np.asarray(v, dtype=np.float64)
    if span_m <= 0:
        return v
    u = np.mod(v, 2 * span_m)
    return np.where(u <= span_m, u, 2 * span_m - u)


class MirroredSurface:
    """A surface model continued beyond its edges by mirror images of itself, for a
    :func:`straight_stroke` longer than the picture.

    Parameters
    ----------
    surface : SurfaceModel
        The picture's surface.
    """

    def __init__(self, surface: Any) -> None:
        self.surface = surface
        self.step_m: float = surface.step_m
        self.tip_radius_m: float = surface.tip_radius_m
        self.surface_per_display: float = surface.surface_per_display
        self.width_m: float = surface.width_m
        self.height_m: float = surface.height_m
        self.w, self.h = self.folded_size(surface.width_m, surface.height_m)

    @staticmethod
    def folded_size(width_m: float, height_m: float) -> tuple[float, float]:
        """Width and height [m] a picture of that size is folded at."""
        return width_m * _INSIDE, height_m * _INSIDE

    def regions(self, x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The surface's regions at the positions folded onto the picture."""
        regions: tuple[np.ndarray, np.ndarray, np.ndarray] = self.surface.regions(fold_into(x_m, self.w),
                                                                                   fold_into(y_m, self.h))
        return regions
