"""A stroke replayed through the surface rendering in simulated time: the pulses the wire fires.

:func:`replay_stroke` is the one whole-stroke path (:func:`tactilize.surface.playback.play_stroke`:
the page's batches, the pen tracker, the rendering's frames, each replacing the events not yet
fired) through a surface rendering of a surface, without a profile.  Deterministic: no wall clock.

Units: SI (s, m).
"""

from __future__ import annotations

from typing import Any, Sequence

from .samples import PenSample
from .tracker import StrokeTracker
from ..surface.events import PulseEvent
from ..surface.playback import BATCH_S, TRANSPORT_S, play_stroke
from ..surface.rendering import SurfaceRendering

__all__ = ["replay_stroke"]


def replay_stroke(
    surface: Any,
    samples: Sequence[PenSample],
    *,
    batch_s: float = BATCH_S,
    transport_s: float = TRANSPORT_S,
    tracker: StrokeTracker | None = None,
) -> list[PulseEvent]:
    """The pulses an event-playing output fires for a stroke (stroke clock [s]).

    Parameters
    ----------
    surface : SurfaceModel or CompositeSurface
    samples : sequence of PenSample
        The stroke, times increasing.
    batch_s : float
        Samples are sent in batches this long [s].
    transport_s : float
        Each batch arrives this long after its newest sample [s].
    """
    played = play_stroke(SurfaceRendering(None, surface), samples, batch_s=batch_s, transport_s=transport_s,
                         tracker=tracker)
    return list(played.events)
