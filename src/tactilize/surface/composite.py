"""Several pictures' surfaces side by side, laid out as :class:`~tactilize.maps.composite.CompositeMap` lays them.

The six-picture view (the paper's Fig. 16) strokes from one picture into the
next: :meth:`CompositeSurface.regions` says which picture each point of the path
is on, so bumps are searched picture by picture and the rendering changes at the
boundary, at the sample spacing of the finer picture (docs/surfaces.md).

Units: SI (metres, display coordinates, y down).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

__all__ = ["CompositeSurface"]


@dataclass(frozen=True, eq=False)
class CompositeSurface:
    """Surface models on a grid of equal cells, row by row.

    Attributes
    ----------
    surfaces : tuple of SurfaceModel
    cols : int
    cell_m : (float, float)
        Cell width and height [m] (the largest picture's).
    """

    surfaces: tuple[Any, ...]
    cols: int
    cell_m: tuple[float, float]

    @classmethod
    def of(cls, surfaces: Sequence[Any], cols: int, cell_m: tuple[float, float] | None = None) -> "CompositeSurface":
        """The grid of ``surfaces``, ``cols`` a row; cells as large as the largest picture by default."""
        if not surfaces or cols < 1:
            raise ValueError("a composite needs at least one surface and one column")
        cell = cell_m or (max(s.width_m for s in surfaces), max(s.height_m for s in surfaces))
        return cls(tuple(surfaces), int(cols), (float(cell[0]), float(cell[1])))

    @property
    def step_m(self) -> float:
        return min(s.step_m for s in self.surfaces)

    @property
    def tip_radius_m(self) -> float:
        return min(s.tip_radius_m / s.surface_per_display for s in self.surfaces)

    surface_per_display = 1.0

    @property
    def width_m(self) -> float:
        """Width of the grid of cells [display m]."""
        return self.cols * self.cell_m[0]

    @property
    def height_m(self) -> float:
        """Height of the grid of cells [display m]."""
        return -(-len(self.surfaces) // self.cols) * self.cell_m[1]

    def regions(self, x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(heights, picture index or -1, prominence floors) at display points [m]."""
        x = np.asarray(x_m, dtype=np.float64)
        y = np.asarray(y_m, dtype=np.float64)
        cw, ch = self.cell_m
        col = np.floor(x / cw).astype(np.intp)
        row = np.floor(y / ch).astype(np.intp)
        idx = row * self.cols + col
        ok = (col >= 0) & (col < self.cols) & (row >= 0) & (idx < len(self.surfaces))
        h = np.full(x.shape, np.nan)
        ids = np.full(x.shape, -1, dtype=np.intp)
        floors = np.zeros(x.shape)
        for i, s in enumerate(self.surfaces):
            m = ok & (idx == i)
            if not m.any():
                continue
            hi, ii, fi = s.regions(x[m] - (i % self.cols) * cw, y[m] - (i // self.cols) * ch)
            h[m] = hi
            ids[m] = np.where(ii < 0, -1, i)
            floors[m] = fi
        return h, ids, floors
