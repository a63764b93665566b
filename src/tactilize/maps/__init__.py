"""Where on the picture: features looked up by position, one stage above :mod:`tactilize.features`.

:mod:`.texturemap`
    :class:`TextureMap` and :func:`texture_map`: local features on a grid of
    tiles, looked up by a physical position [m] in O(1).
:mod:`.composite`
    :class:`CompositeMap`: several pictures' maps side by side as one surface
    (the paper's Fig. 16).
"""

from __future__ import annotations

from .composite import CompositeMap
from .texturemap import TextureMap, texture_map

__all__ = ["CompositeMap", "TextureMap", "texture_map"]
