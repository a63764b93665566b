"""Stroke speed and direction from the pen samples' own timestamps: :mod:`tactilize.surface.tracker`
(the whole-stroke path, :mod:`tactilize.surface.playback`, tracks a stroke below the pen's layer),
under the pen's name."""

from __future__ import annotations

from ..surface.tracker import StrokeState, StrokeTracker

__all__ = ["StrokeState", "StrokeTracker"]
