"""Several pictures side by side as one surface: the paper's Fig. 16.

The paper's pen demonstration strokes six textures laid side by side, the
drive following the texture under the pen.  :class:`CompositeMap` puts texture
maps on a grid of equal cells (each picture at its physical size in the
top-left of its cell) and looks up the one under the pen, so the pen renderer
takes it like any :class:`~tactilize.maps.texturemap.TextureMap`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

if TYPE_CHECKING:  # types only: a composite loads nothing until its maps do
    from ..features import TextureFeatures
    from .lookup import FeatureLookup

__all__ = ["CompositeMap"]


@dataclass(frozen=True, eq=False)
class CompositeMap:
    """Texture maps on a grid, row by row, in equal cells.

    Attributes
    ----------
    maps : tuple of TextureMap
        The pictures' maps, row-major.
    cols : int
        Cells per row.
    cell_m : (float, float)
        Cell width and height [m]: the largest picture's.
    """

    maps: tuple[FeatureLookup, ...]
    cols: int
    cell_m: tuple[float, float]

    @classmethod
    def of(cls, maps: Sequence[FeatureLookup], cols: int) -> "CompositeMap":
        """The grid of ``maps`` with ``cols`` cells a row (cells as large as the largest picture)."""
        if not maps or cols < 1:
            raise ValueError("a composite needs at least one map and one column")
        return cls(tuple(maps), int(cols), (max(m.width_m for m in maps), max(m.height_m for m in maps)))

    @property
    def rows(self) -> int:
        return -(-len(self.maps) // self.cols)

    @property
    def width_m(self) -> float:
        """Width of the whole surface [m]."""
        return self.cols * self.cell_m[0]

    @property
    def height_m(self) -> float:
        """Height of the whole surface [m]."""
        return self.rows * self.cell_m[1]

    def origin_m(self, index: int) -> tuple[float, float]:
        """Top-left corner [m] of picture ``index`` on the surface (y down)."""
        return (index % self.cols) * self.cell_m[0], (index // self.cols) * self.cell_m[1]

    def lookup(self, x_m: float, y_m: float) -> TextureFeatures | None:
        """Features under a point of the surface (from its top-left, y down) [m]; None off every picture."""
        cw, ch = self.cell_m
        if not (0.0 <= x_m < self.width_m and 0.0 <= y_m < self.height_m):
            return None
        col, row = int(x_m / cw), int(y_m / ch)
        i = row * self.cols + col
        if i >= len(self.maps):
            return None
        return self.maps[i].lookup(x_m - col * cw, y_m - row * ch)
