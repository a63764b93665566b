"""Where on the picture: features looked up by position, one stage above :mod:`tactilize.features`.

:mod:`.texturemap`
    :class:`TextureMap` and :func:`texture_map`: local features on a grid of
    tiles, looked up by a physical position [m] in O(1).
:mod:`.composite`
    :class:`CompositeMap`: several pictures' maps side by side as one surface
    (the paper's Fig. 16).
:mod:`.lookup`
    :class:`FeatureLookup`, the feature-lookup interface both satisfy: what the
    pen renderer and the pen server take as the picture under the pen.
:mod:`.spectrumview`
    The paper's Fig. 5 as data (log spectrum, the dominant peak, the tiles),
    for the page's spectrum view and ``analyze --plot``; imported by its users.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # what the checker sees; at run time __getattr__ below
    from .composite import CompositeMap
    from .lookup import FeatureLookup
    from .texturemap import TextureMap, texture_map

__all__ = ["CompositeMap", "FeatureLookup", "TextureMap", "texture_map"]

# name -> module; loaded on first use, so a composite or the lookup interface alone does
# not load the FFT stack a texture map needs.
_EXPORTS = {"CompositeMap": "composite", "FeatureLookup": "lookup", "TextureMap": "texturemap", "texture_map": "texturemap"}


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        from importlib import import_module

        return getattr(import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
