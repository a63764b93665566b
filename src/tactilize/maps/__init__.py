"""Where on the picture: features looked up by position, one stage above :mod:`tactilize.features`.

:mod:`.texturemap`
    :class:`TextureMap` and :func:`texture_map`: local features on a grid of
    tiles, looked up by a physical position [m] in O(1).
:mod:`.composite`
    :class:`CompositeMap`: several pictures' maps side by side as one surface
    (the paper's Fig. 16).
:mod:`.lookup`
    :class:`FeatureLookup`, the feature-lookup protocol both satisfy: what the
    pen renderer and the pen server take as the picture under the pen.
:mod:`.spectrumview`
    The paper's Fig. 5 as data (log spectrum, the dominant peak, the tiles),
    for the page's spectrum view and ``analyze --plot``; imported by its users.
"""

from __future__ import annotations

from .composite import CompositeMap
from .lookup import FeatureLookup
from .texturemap import TextureMap, texture_map

__all__ = ["CompositeMap", "FeatureLookup", "TextureMap", "texture_map"]
