"""The tactile pen in software: stroke tracking and real-time rendering.

The paper's pen system (its Fig. 6) tracks the pen on a tablet while the texture
picture is shown on a display, and drives the two actuators in the pen's grip
with the texture *under the pen*, at a frequency that follows the stroking
speed.  This package holds that loop, in three modules:

:mod:`.samples`
    :class:`PenSample`, one timestamped position, and the check that a sample
    can be tracked.
:mod:`.tracker`
    :class:`StrokeTracker`: speed [m/s] and direction [rad] of the stroke from
    the samples' *own* timestamps (never the arrival time: samples come in
    bursts, coalesced to the display's frame rate).  A least-squares line
    through the last ~30 ms of samples; robust to jitter, duplicate and
    out-of-order samples, gaps, clock resets and jumps.
:mod:`.renderer`
    :class:`PenRenderer`: feeds the tracker, looks the texture up under the
    pen, asks the profile for the drive, splits it over the two channels and
    applies it to an :class:`~tactilize.actuators.base.Output`.  Lifting the
    pen or leaving the picture stops the output at once.

Frames
------
Positions are metres from the picture's top-left corner with y pointing *down*
(screen coordinates, as pointers report them and as
:meth:`~tactilize.maps.texturemap.TextureMap.lookup` takes them).  Directions are
counter-clockwise from +x with y pointing *up* (the frame of
``TextureFeatures.orientation_deg`` and ``Profile.drive``), so a stroke moving up
the screen has direction +pi/2.

The pages report positions in CSS pixels and times in milliseconds; reading
those rows is the web's job (:mod:`tactilize.web.rows`).
"""

from __future__ import annotations

from .renderer import PenRenderer, RenderResult, default_splitter
from .samples import PenSample, is_trackable
from .tracker import StrokeState, StrokeTracker

__all__ = [
    "PenSample",
    "is_trackable",
    "StrokeState",
    "StrokeTracker",
    "RenderResult",
    "PenRenderer",
    "default_splitter",
]
