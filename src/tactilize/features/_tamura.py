"""Tamura coarseness and directionality, the element-size descriptors."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["tamura_features"]


def tamura_features(pixels: np.ndarray, max_side: int = 256) -> dict[str, float]:
    """Tamura coarseness and directionality of a grey image.

    Coarseness: for window sizes 2^k (k = 1..5), the largest difference between
    averages on opposite sides picks each pixel's best size; its mean is the
    coarseness [1]_.  Directionality: 1 minus the spread of gradient directions
    around their main peak, normalised so that a uniform histogram gives 0 and
    a single direction 1.

    Parameters
    ----------
    pixels : ndarray, shape (H, W)
        Grey levels.
    max_side : int
        The image is block-averaged to at most this many pixels a side first:
        the descriptors are about element size, not fine detail.

    Returns
    -------
    dict
        ``coarseness_px`` [pixels of the input] and ``directionality`` in
        [0, 1]; both 0 for an image too small (under 8 pixels a side after
        reduction) or constant.

    References
    ----------
    .. [1] H. Tamura, S. Mori and T. Yamawaki, "Textural features corresponding
       to visual perception", IEEE Transactions on Systems, Man, and
       Cybernetics 8(6), 460-473, 1978.
    """
    from scipy import ndimage

    a = np.asarray(pixels, dtype=np.float32)
    factor = max(1, math.ceil(max(a.shape) / max_side))
    if factor > 1:
        hh, ww = (a.shape[0] // factor) * factor, (a.shape[1] // factor) * factor
        a = a[:hh, :ww].reshape(hh // factor, factor, ww // factor, factor).mean(axis=(1, 3))
    if min(a.shape) < 8 or float(a.std()) < 1e-6:
        return {"coarseness_px": 0.0, "directionality": 0.0}

    best_e = np.zeros(a.shape, np.float32)
    best_k = np.ones(a.shape, np.float32)
    for k in range(1, 6):
        size = 2**k
        if size * 2 > min(a.shape):
            break
        avg = ndimage.uniform_filter(a, size=size, mode="reflect")
        half = size // 2
        eh = np.abs(np.roll(avg, -half, axis=1) - np.roll(avg, half, axis=1))
        ev = np.abs(np.roll(avg, -half, axis=0) - np.roll(avg, half, axis=0))
        e = np.maximum(eh, ev)
        better = e > best_e
        best_e = np.where(better, e, best_e)
        best_k = np.where(better, float(size), best_k)
    coarseness = float(best_k.mean()) * factor

    gy, gx = map(np.asarray, np.gradient(a))
    g = np.hypot(gx, gy)
    strong = g > max(1e-6, 0.1 * float(g.max()))
    if not strong.any():
        return {"coarseness_px": coarseness, "directionality": 0.0}
    theta = np.mod(np.arctan2(gy[strong], gx[strong]), np.pi)
    hist, edges = np.histogram(theta, bins=16, range=(0, np.pi), weights=g[strong])
    hist = hist / float(hist.sum())
    centres = 0.5 * (edges[:-1] + edges[1:])
    peak = centres[int(np.argmax(hist))]
    dist = np.abs((centres - peak + np.pi / 2) % np.pi - np.pi / 2)
    spread = float((hist * dist**2).sum())
    uniform = float((dist**2).mean())
    directionality = float(min(1.0, max(0.0, 1.0 - spread / uniform)))
    return {"coarseness_px": coarseness, "directionality": directionality}
