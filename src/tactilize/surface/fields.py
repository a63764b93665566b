"""Height fields generated in code, with their bumps known: for tests, benches and demos.

Every field is an array of heights in luminance units (0 .. 1) plus the centres
and radii of its bumps, so what a stroke should feel is known exactly.
Deterministic for a given seed.

Units: SI (metres).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

__all__ = ["BumpField", "bump_field", "grain_field", "grating_field"]


class BumpField(NamedTuple):
    """Heights with known bumps.

    Attributes
    ----------
    heights : ndarray of float32, shape (rows, cols)
        In luminance units, 0 (flat ground) .. 1.
    pitch_m : float
        Pixel size [m].
    centres_m : ndarray, shape (n, 2)
        Bump centres (x, y) [m] from the top-left, y down.
    radii_m : ndarray, shape (n,)
        Bump radii [m]: each bump is a raised cosine that is 0 at this distance.
    """

    heights: np.ndarray
    pitch_m: float
    centres_m: np.ndarray
    radii_m: np.ndarray


def bump_field(
    centres_m: np.ndarray, radii_m: np.ndarray, size_m: tuple[float, float], pitch_m: float,
    peaks: np.ndarray | None = None,
) -> BumpField:
    """Raised-cosine bumps at ``centres_m`` (x, y) [m] of ``radii_m`` [m] and heights
    ``peaks`` (1 by default) on flat ground, ``size_m`` (width, height) [m] at ``pitch_m``."""
    cols, rows = int(round(size_m[0] / pitch_m)), int(round(size_m[1] / pitch_m))
    h = np.zeros((rows, cols), np.float32)
    centres = np.asarray(centres_m, dtype=np.float64).reshape(-1, 2)
    radii = np.broadcast_to(np.asarray(radii_m, dtype=np.float64), (len(centres),)).copy()
    amp = np.ones(len(centres)) if peaks is None else np.asarray(peaks, dtype=np.float64)
    for (cx, cy), r, a in zip(centres, radii, amp):
        c0, c1 = max(0, int((cx - r) / pitch_m)), min(cols, int((cx + r) / pitch_m) + 2)
        r0, r1 = max(0, int((cy - r) / pitch_m)), min(rows, int((cy + r) / pitch_m) + 2)
        if c0 >= c1 or r0 >= r1:
            continue
        xs = (np.arange(c0, c1) + 0.5) * pitch_m - cx
        ys = (np.arange(r0, r1) + 0.5) * pitch_m - cy
        d = np.hypot(xs[None, :], ys[:, None])
        bump = np.where(d < r, 0.5 * a * (1.0 + np.cos(np.pi * np.minimum(d / r, 1.0))), 0.0)
        np.maximum(h[r0:r1, c0:c1], bump.astype(np.float32), out=h[r0:r1, c0:c1])
    return BumpField(h, float(pitch_m), centres, radii)


def grain_field(pitch_m: float, size_m: tuple[float, float], *, px_per_pitch: int = 10, jitter: float = 0.3,
                radius_share: float = 0.45, seed: int = 0) -> BumpField:
    """Space-filling grains (sandpaper-like): one bump per cell of a square grid of
    ``pitch_m`` [m], each moved up to ``jitter`` of a pitch, radius ``radius_share``
    of a pitch, height 0.6 .. 1; not periodic."""
    rng = np.random.default_rng(seed)
    nx, ny = int(math.ceil(size_m[0] / pitch_m)), int(math.ceil(size_m[1] / pitch_m))
    gx, gy = np.meshgrid(np.arange(nx) + 0.5, np.arange(ny) + 0.5)
    centres = np.stack([gx.ravel(), gy.ravel()], 1) * pitch_m
    centres += rng.uniform(-jitter, jitter, centres.shape) * pitch_m
    radii = np.full(len(centres), radius_share * pitch_m)
    return bump_field(centres, radii, size_m, pitch_m / px_per_pitch, rng.uniform(0.6, 1.0, len(centres)))


def grating_field(spatial_frequency_per_m: float, angle_rad: float, size_m: tuple[float, float],
                  pitch_m: float) -> np.ndarray:
    """A sinusoidal grating 0 .. 1 whose wave vector points at ``angle_rad`` [rad] from +x
    (y up, as ``TextureFeatures.orientation_deg``), ``spatial_frequency_per_m`` [1/m]."""
    cols, rows = int(round(size_m[0] / pitch_m)), int(round(size_m[1] / pitch_m))
    x = (np.arange(cols) + 0.5) * pitch_m
    y = -(np.arange(rows) + 0.5) * pitch_m  # y up
    phase = 2 * np.pi * spatial_frequency_per_m * (x[None, :] * math.cos(angle_rad) + y[:, None] * math.sin(angle_rad))
    return (0.5 + 0.5 * np.cos(phase)).astype(np.float32)
