"""The feature-lookup interface: what the pen renderer and the pen server take as "the picture".

A :class:`~tactilize.maps.texturemap.TextureMap` (one picture's tiles) and a
:class:`~tactilize.maps.composite.CompositeMap` (several pictures side by side)
both satisfy it, and so does anything else that can say which texture lies
under a point: a test's stub, a map read back from a catalog.

Units: metres, from the picture's top-left corner, y pointing down.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from ..features import TextureFeatures

__all__ = ["FeatureLookup"]


@runtime_checkable
class FeatureLookup(Protocol):
    """Texture features by position on a displayed picture."""

    @property
    def width_m(self) -> float:
        """Displayed width [m]."""
        ...

    @property
    def height_m(self) -> float:
        """Displayed height [m]."""
        ...

    def lookup(self, x_m: float, y_m: float) -> TextureFeatures | None:
        """The features under (``x_m``, ``y_m``) [m, from the top-left, y down]; None off the picture."""
        ...
