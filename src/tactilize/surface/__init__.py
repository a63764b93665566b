"""Surfaces as they are: a picture as a height field under a stylus tip, and pulse events along the stroke.

docs/surfaces.md is the design: :mod:`.model` (the height field through the tip,
made once per picture), :mod:`.bumps` (bumps along a path), :mod:`.events`
(one pulse per bump crossed, its strength in the felt band), :mod:`.stroke`
(the same in real time, predicted ahead), :mod:`.path` (the stroke's path kept
between batches), :mod:`.straight` (a steady stroke for the commands and the
catalogue), :mod:`.rendering` (the rendering interface: :func:`rendering_for`,
a frame of events and their Drive per pen batch, and :func:`rendered_drive`), :mod:`.equivalent` (the steady Drive
of the next window for outputs that cannot play events), :mod:`.composite`
(several pictures side by side) and :mod:`.fields` (generated fields with known
bumps).  A stroke replayed through the real-time path is the pen's
(:mod:`tactilize.pen.replay`).
"""

from __future__ import annotations

from .bumps import Crossings, crossings_along, resample_path
from .composite import CompositeSurface
from .events import EventStatistics, PulseEvent, event_statistics, place_events, strength_of
from .model import TIP_RADIUS_M, SurfaceLike, SurfaceModel, surface_model
from .rendering import Frame, Rendering, rendered_drive, rendering_for, stroke_events
from .straight import straight_stroke
from .stroke import SurfaceStroke

__all__ = [
    "Crossings",
    "EventStatistics",
    "SurfaceLike",
    "Frame",
    "Rendering",
    "rendered_drive",
    "rendering_for",
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
