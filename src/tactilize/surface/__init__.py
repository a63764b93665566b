"""Surfaces as they are: a picture as a height field under a stylus tip, and pulse events along the stroke.

docs/surfaces.md is the design: :mod:`.model` (the height field through the tip,
made once per picture), :mod:`.bumps` (bumps along a path), :mod:`.events`
(one pulse per bump crossed, its strength in the felt band), :mod:`.stroke`
(the same in real time, predicted ahead), :mod:`.equivalent` (the steady Drive
of the next window for outputs that cannot play events), :mod:`.composite`
(several pictures side by side) and :mod:`.fields` (generated fields with known
bumps).  A stroke replayed through the real-time path is the pen's
(:mod:`tactilize.pen.replay`).
"""

from __future__ import annotations

from .bumps import Crossings, crossings_along, resample_path
from .composite import CompositeSurface
from .events import PulseEvent, event_statistics, place_events, stroke_events, strength_of
from .model import TIP_RADIUS_M, SurfaceModel, surface_model
from .stroke import SurfaceStroke

__all__ = [
    "Crossings",
    "CompositeSurface",
    "PulseEvent",
    "SurfaceModel",
    "SurfaceStroke",
    "TIP_RADIUS_M",
    "crossings_along",
    "event_statistics",
    "place_events",
    "resample_path",
    "stroke_events",
    "strength_of",
    "surface_model",
]
