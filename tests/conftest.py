"""Shared fixtures: every test image is generated here, never downloaded."""

from __future__ import annotations

import math

import numpy as np
import pytest

METRES_PER_INCH = 0.0254


def grating_array(
    shape: tuple[int, int],
    frequency_per_m: float,
    angle_deg: float,
    dpi: float,
    *,
    contrast: float = 1.0,
    mean: float = 0.5,
    noise: float = 0.0,
    phase: float = 0.3,
    quantise: bool = True,
    seed: int = 0,
) -> np.ndarray:
    """A sinusoidal grating written independently of the library.

    The wave vector points at ``angle_deg`` counter-clockwise from +x with y up
    the picture (row 0 is the top), which is the convention the library reports.
    """
    h, w = shape
    pitch = METRES_PER_INCH / dpi
    rows, cols = np.mgrid[0:h, 0:w]
    x_m = cols * pitch
    y_up_m = -rows * pitch
    theta = math.radians(angle_deg)
    arg = 2 * math.pi * frequency_per_m * (x_m * math.cos(theta) + y_up_m * math.sin(theta)) + phase
    img = mean + 0.5 * contrast * np.cos(arg)
    if noise:
        img = img + noise * np.random.default_rng(seed).standard_normal(img.shape)
    img = np.clip(img, 0.0, 1.0)
    if quantise:
        img = np.round(img * 255.0) / 255.0
    return img.astype(np.float32)


@pytest.fixture
def make_grating():
    return grating_array
