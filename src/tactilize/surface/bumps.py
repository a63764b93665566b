"""Bumps along a path: local maxima of the tip-filtered profile with a prominence rule.

A path (timestamped positions) is resampled at the surface's spatial step
(:attr:`~tactilize.surface.model.SurfaceModel.step_m`), the tip-filtered height is
read along it, and every local maximum whose prominence (``scipy.signal.find_peaks``:
its height above the higher of the lowest points separating it from a higher
peak on either side) is at least the surface's floor is a bump the tip crosses,
at the time the path reaches it (docs/surfaces.md, "What is rendered").
Bumps are found within one region at a time (one picture of a composite), so
the step between two pictures is never a bump.

Units: SI (s, m); heights and prominences in luminance units.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from scipy.signal import find_peaks  # at import: a first stroke must not wait for it (0.5 s and more)

try:
    # find_peaks' own two steps (its local maxima, their prominences), called without its
    # argument handling: that handling is half of what a pen batch's search costs.
    from scipy.signal._peak_finding_utils import _local_maxima_1d, _peak_prominences
except ImportError:  # another scipy: find_peaks itself
    _local_maxima_1d = _peak_prominences = None

from .model import SurfaceLike

__all__ = ["Crossings", "resample_path", "crossings_along", "bumps_in"]


class Crossings(NamedTuple):
    """Bumps crossed along a path, in path order.

    Attributes
    ----------
    t_s : ndarray
        Time the tip reaches each bump [s].
    s_m : ndarray
        Arc length along the path [display m] (grows through reversals).
    x_m, y_m : ndarray
        Where [display m, y down].
    prominence : ndarray
        Each bump's prominence [luminance units].
    floor : ndarray
        The prominence floor of the picture it is on.
    """

    t_s: np.ndarray
    s_m: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    prominence: np.ndarray
    floor: np.ndarray


def resample_path(t_s: Any, x_m: Any, y_m: Any, step_m: float, s0_m: float = 0.0) -> tuple[np.ndarray, ...]:
    """Points every ``step_m`` [m] of arc along the polyline through the samples.

    Samples that do not move (a resting pen) add no arc; times between vertices
    are linear in arc length (constant speed along each segment).

    Returns
    -------
    (t_s, x_m, y_m, s_m) : ndarrays
        ``s_m`` counts from ``s0_m`` at the first sample.
    """
    t = np.asarray(t_s, dtype=np.float64)
    x = np.asarray(x_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    d = np.hypot(np.diff(x), np.diff(y))
    keep = np.concatenate(([True], d > 0))
    t, x, y = t[keep], x[keep], y[keep]
    s = s0_m + np.concatenate(([0.0], np.cumsum(d[d > 0])))
    if s.size < 2:
        return t[:1], x[:1], y[:1], s[:1]
    n = int((s[-1] - s[0]) / step_m) + 1
    grid = s[0] + step_m * np.arange(n)
    return np.interp(grid, s, t), np.interp(grid, s, x), np.interp(grid, s, y), grid


def crossings_along(surface: SurfaceLike, t_s: np.ndarray, x_m: np.ndarray, y_m: np.ndarray, s_m: np.ndarray) -> Crossings:
    """The bumps of ``surface`` crossed along an already resampled path.

    Parameters
    ----------
    surface : SurfaceLike
        Its ``regions(x_m, y_m) -> (heights, region ids, floors)`` is read.
    t_s, x_m, y_m, s_m : ndarray
        The resampled path (:func:`resample_path`).
    """
    h, ids, floors = surface.regions(x_m, y_m)
    idx, proms = bumps_in(h, ids, floors)
    if idx.size == 0:
        empty = np.zeros(0)
        return Crossings(empty, empty, empty, empty, empty, empty)
    return Crossings(t_s[idx], s_m[idx], x_m[idx], y_m[idx], proms, floors[idx])


_NONE = (np.zeros(0, dtype=np.intp), np.zeros(0))


def bumps_in(h: np.ndarray, ids: np.ndarray, floors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices and prominences of the bumps of a profile (the one rule of what a bump is).

    Parameters
    ----------
    h : ndarray
        Tip-filtered heights along the path, at equal steps of arc [luminance units].
    ids : ndarray of int
        The region (picture) of each point, -1 off every picture.
    floors : ndarray
        The prominence floor at each point.

    Returns
    -------
    (indices, prominences) : ndarrays
        In path order; searched within each run of one region, never across two.
    """
    n = ids.size
    if n < 3:
        return _NONE
    first = ids[0]
    if first >= 0 and ids[-1] == first and (ids == first).all():
        # One picture all along (the usual case): one search.
        return _peaks(h, float(floors[0]))
    # Runs of one region (a picture); -1 (off every picture) is never searched.
    picked: list[np.ndarray] = []
    proms: list[np.ndarray] = []
    edges = np.flatnonzero(np.diff(ids)) + 1
    starts = np.concatenate(([0], edges))
    ends = np.concatenate((edges, [n]))
    for a, b in zip(starts.tolist(), ends.tolist()):
        if ids[a] < 0 or b - a < 3:
            continue
        idx, prom = _peaks(h[a:b], float(floors[a]))
        if idx.size:
            picked.append(idx + a)
            proms.append(prom)
    if not picked:
        return _NONE
    return np.concatenate(picked), np.concatenate(proms)


def _peaks(h: np.ndarray, floor: float) -> tuple[np.ndarray, np.ndarray]:
    """``find_peaks(h, prominence=floor)``: (indices, prominences) of the local maxima whose
    prominence is at least ``floor``."""
    if _local_maxima_1d is None or _peak_prominences is None:
        idx, props = find_peaks(h, prominence=floor)
        return idx, props["prominences"]
    x = np.ascontiguousarray(h, dtype=np.float64)
    peaks = _local_maxima_1d(x)[0]
    prom = _peak_prominences(x, peaks, -1)[0]  # -1: no window, as find_peaks without wlen
    keep = floor <= prom
    return peaks[keep], prom[keep]
