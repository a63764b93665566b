"""Height fields generated in code, with their bumps known: for tests, benches and demos;
strokes over them (minimum-jerk paths) and the times they truly cross each bump.

Every field is an array of heights in luminance units (0 .. 1) plus the centres
and radii of its bumps, so what a stroke should feel is known exactly.
Deterministic for a given seed.

Units: SI (metres).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

__all__ = ["BumpField", "bump_field", "grain_field", "grating_field", "bump_line_field", "min_jerk_path", "true_crossings"]


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
    centres_m: np.ndarray, radii_m: np.ndarray | float, size_m: tuple[float, float], pitch_m: float,
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


def bump_line_field(seed: int, radius_m: float = 0.6e-3, beside: int = 20) -> tuple[BumpField, float]:
    """Non-overlapping bumps of ``radius_m`` [m] along a stroke line, each within half a radius
    of it, and ``beside`` more 2.5 .. 5 radii off it (never crossed), on an 80 x 20 mm field
    at 50 um pixels.  Returns the field and the line's y [m]."""
    rng = np.random.default_rng(seed)
    cx = 4e-3 + np.cumsum(2.8 * radius_m + rng.exponential(1.5e-3, 80))
    cx = cx[cx < 76e-3]
    y0 = 10e-3
    centres = np.stack([cx, y0 + rng.uniform(-0.5, 0.5, cx.size) * radius_m], 1)
    if beside:
        side = np.stack([rng.uniform(4e-3, 76e-3, beside),
                         y0 + rng.choice([-1, 1], beside) * rng.uniform(2.5, 5, beside) * radius_m], 1)
        centres = np.concatenate([centres, side])
    return bump_field(centres, radius_m, (80e-3, 20e-3), 0.05e-3), y0


def min_jerk_path(points_m, durations_s, holds_s, rate_hz: float = 240.0) -> tuple[np.ndarray, np.ndarray]:
    """A hand's stroke along one axis: minimum-jerk moves between ``points_m`` [m], each
    taking its duration [s] and followed by a rest of its hold [s] (a stop; a move back is
    a reversal), sampled at ``rate_hz`` [Hz].  Returns times [s] and positions [m]."""
    t: list[float] = []
    x: list[float] = []
    t0 = 0.0
    for a, b, T, hold in zip(points_m[:-1], points_m[1:], durations_s, holds_s):
        tt = np.arange(0.0, T, 1.0 / rate_hz)
        tau = tt / T
        x += list(a + (b - a) * (10 * tau**3 - 15 * tau**4 + 6 * tau**5))
        t += list(t0 + tt)
        t0 += T
        th = np.arange(0.0, hold, 1.0 / rate_hz)
        x += [b] * th.size
        t += list(t0 + th)
        t0 += hold
    return np.array(t), np.array(x)


def true_crossings(t_s: np.ndarray, x_m: np.ndarray, y_m: np.ndarray, centres_m: np.ndarray,
                   radii_m: np.ndarray | float) -> np.ndarray:
    """Times [s] the path (samples t, x, y [s, m], linearly between them) passes its closest
    approach to a bump centre within that bump's radius [m], in order (a pen resting on a
    bump's top has no strict closest approach there and is not counted)."""
    td = np.linspace(t_s[0], t_s[-1], int((t_s[-1] - t_s[0]) * 20_000) + 2)
    xd, yd = np.interp(td, t_s, x_m), np.interp(td, t_s, y_m)
    radii = np.broadcast_to(np.asarray(radii_m, dtype=float), (len(centres_m),))
    out: list[float] = []
    for (cx, cy), r in zip(np.asarray(centres_m, dtype=float), radii):
        d = np.hypot(xd - cx, yd - cy)
        i = np.flatnonzero((d[1:-1] <= d[:-2]) & (d[1:-1] < d[2:]) & (d[1:-1] < r)) + 1
        out.extend(td[i].tolist())
    return np.sort(np.array(out))
