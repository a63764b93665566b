"""One pen sample, in SI, and the check that it can be tracked: :mod:`tactilize.surface.samples`
(the whole-stroke path, :mod:`tactilize.surface.playback`, tracks a stroke below the pen's layer),
under the pen's name."""

from __future__ import annotations

from ..surface.samples import PenSample, is_trackable

__all__ = ["PenSample", "is_trackable"]
