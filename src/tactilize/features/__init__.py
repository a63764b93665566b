"""Texture features from the 2-D Fourier transform of an image.

The paper extracts two numbers from an image's Fourier transform: the spatial
frequency of its dominant periodic component, ``f_s`` [cycles/m], and that
component's *spectral intensity* ``i_s`` in [0, 1] [1]_.  This package
measures them, plus what the paper names as future work: descriptors of
textures that are not periodic (contrast, roughness, orientation and
anisotropy, Tamura coarseness and directionality).

Everything is measured in cycles per pixel and converted to cycles per metre
with the image's pixel pitch, so :meth:`TextureFeatures.at_pitch` gives the
same texture shown at another size without a new FFT.

Conventions
-----------
Angles are counter-clockwise from the image's +x axis (rightwards) with y
pointing *up* the picture, in degrees for ``orientation_deg``.  The wave vector
is perpendicular to the ridges of a grating: vertical stripes have orientation 0.

Layout
------
``_texture``
    :class:`TextureFeatures`, the result, and its physical units.
``_analysis``
    :func:`extract_features` and :func:`analyse_stack`: the pipeline.
``_spectrum``
    The window and FFT, and every per-image number read off the spectra, in
    NumPy over the whole stack.
``_kernels``
    The two compiled passes (numba): the window, and the sums over each
    spectrum with its strongest bin.  Loaded on the first analysis.
``_tamura``
    Tamura coarseness and directionality.

References
----------
.. [1] docs/references.md, section 1: the paper's laws and i_s.
"""

from __future__ import annotations

from ._analysis import (
    MIN_SIDE_PX,
    analyse_stack,
    extract_features,
    radial_profile,
    warm_up,
)
from ._tamura import tamura_features
from ._texture import NO_PEAK, TextureFeatures

__all__ = [
    "MIN_SIDE_PX",
    "NO_PEAK",
    "TextureFeatures",
    "analyse_stack",
    "extract_features",
    "radial_profile",
    "tamura_features",
    "warm_up",
]
