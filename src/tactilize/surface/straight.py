"""What the surface rendering gives a steady straight stroke: events and their equivalent Drive.

The commands that take a picture and a speed (``drive``, ``simulate``,
``profile report``) stroke the picture through its centre at that speed, for up
to :data:`STROKE_S`, back and forth where the picture is shorter, and summarise
the events by rate, interval CV and strength (docs/surfaces.md, "Where it is
measured"); :meth:`tactilize.surface.rendering.SurfaceRendering.steady_drive` reads it.

Units: SI (m, s, Hz).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..drive import Drive
from .equivalent import drive_of_statistics
from .events import EventStatistics, PulseEvent, event_statistics, stroke_events
from .model import SurfaceLike

__all__ = ["straight_stroke", "surface_stroke_drive", "STROKE_S", "STROKE_RATE_HZ"]

#: Length of the steady stroke [s].
STROKE_S = 2.0
#: Its sample rate [Hz] (a pen tablet's).
STROKE_RATE_HZ = 240.0
#: Kept this far from the picture's edges [m].
_MARGIN_M = 1e-3


def straight_stroke(width_m: float, height_m: float, speed_m_s: float, direction_rad: float = 0.0,
                    duration_s: float = STROKE_S) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples (t [s], x [m], y [m], y down) of a steady stroke through a picture's centre,
    back and forth along the chord where the stroke is longer than the picture."""
    t = np.arange(0.0, duration_s, 1.0 / STROKE_RATE_HZ)
    ux, uy = math.cos(direction_rad), -math.sin(direction_rad)
    cx, cy = width_m / 2, height_m / 2
    # Half the chord through the centre along the direction, inside the margins.
    reach = [(w / 2 - _MARGIN_M) / abs(u) for w, u in ((width_m, ux), (height_m, uy)) if abs(u) > 1e-12]
    half = max(min(reach), 1e-6)
    travel = speed_m_s * t
    # A triangle wave: forward over the chord, then back.
    phase = np.mod(travel, 4 * half)
    s = np.where(phase < 2 * half, phase, 4 * half - phase) - half
    return t, cx + ux * s, cy + uy * s


def surface_stroke_drive(surface: SurfaceLike, profile: Any, speed_m_s: float, direction_rad: float | None = None,
                         pressure: float | None = None) -> tuple[Drive, list[PulseEvent], EventStatistics]:
    """The events of a steady stroke on ``surface``, their statistics over the whole stroke and
    their equivalent Drive (:func:`~.equivalent.drive_of_statistics`)."""
    if speed_m_s <= 0:
        return Drive.off(), [], event_statistics([])
    t, x, y = straight_stroke(surface.width_m, surface.height_m, speed_m_s, direction_rad or 0.0)
    events = stroke_events(surface, t, x, y, pressure)
    stats = event_statistics(events, float(t[-1]))
    return drive_of_statistics(stats, profile), events, stats
