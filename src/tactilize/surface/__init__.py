"""Surfaces as they are: a picture as a height field under a stylus tip, and pulse events along the stroke.

docs/surfaces.md is the design: :mod:`.model` (the height field through the tip,
made once per picture), :mod:`.bumps` (bumps along a path), :mod:`.events`
(one pulse per bump crossed, its strength in the felt band), :mod:`.stroke`
(the same in real time, predicted ahead), :mod:`.path` (the stroke's path kept
between batches), :mod:`.straight` (a steady stroke for the commands and the
catalogue, and :func:`rendered_drive`), :mod:`.equivalent` (the steady Drive
of the next window for outputs that cannot play events), :mod:`.composite`
(several pictures side by side) and :mod:`.fields` (generated fields with known
bumps).  A stroke replayed through the real-time path is the pen's
(:mod:`tactilize.pen.replay`).
"""

from __future__ import annotations

from .bumps import Crossings, crossings_along, resample_path
from .composite import CompositeSurface
from .events import EventStatistics, PulseEvent, event_statistics, place_events, stroke_events, strength_of
from .model import TIP_RADIUS_M, SurfaceLike, SurfaceModel, surface_model
from .straight import rendered_drive, straight_stroke
from .stroke import SurfaceStroke

__all__ = [
    "Crossings",
    "EventStatistics",
    "SurfaceLike",
    "rendered_drive",
    "straight_stroke",
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
