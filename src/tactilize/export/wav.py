"""A stroke over a surface as a WAV file: the tip's vertical acceleration, for voice coils.

For a profile whose rendering is ``surface`` (docs/surfaces.md) a WAV carries the
signal a voice coil should play (:mod:`tactilize.synthesis.acceleration`): the
tip's acceleration along the stroke, band-limited to the actuator's band, at
full scale where it reaches
:data:`~tactilize.synthesis.acceleration.FULL_SCALE_ACCELERATION` (on a surface in metres
:data:`~tactilize.materials.FULL_SCALE_ACCELERATION_M_S2`), signed 16-bit
PCM, the same signal on both channels (as the stroke's other exports give both
actuators the same drive).  A steady profile's WAV is still its pulse train
(:mod:`.steady`).  :func:`stroke_wav_source` is that choice, for the CLI and the page alike.

Units: SI (s, m, Hz).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..surface.model import SurfaceModel
    from .stroke import Stroke
    from .timeline import DriveTimeline


__all__ = ["StrokeAcceleration", "stroke_wav_source"]


@dataclass(frozen=True)
class StrokeAcceleration:
    """A stroke on a surface, to be rendered as the tip's acceleration.

    Attributes
    ----------
    stroke : tactilize.export.Stroke
        The pen samples (SI, y down), pressure where known.
    surface : SurfaceModel
        The picture's height field.
    start_s, end_s : float
        The span written [s], on the stroke's clock.
    mirror : bool
        The picture continues beyond its edges with mirror images (a synthetic
        stroke longer than the picture, as :func:`~tactilize.export.run_stroke` shows it).
    gain : float
        Multiplies the signal before the full-scale clip.
    """

    stroke: Stroke
    surface: SurfaceModel
    start_s: float
    end_s: float
    mirror: bool = False
    gain: float = 1.0

    def samples(self, sample_rate_hz: float, channels: int = 2) -> tuple[np.ndarray, int]:
        """(samples (n, channels) in [-1, 1], how many were clipped); made once per rate."""
        cache = self.__dict__.setdefault("_rendered", {})
        if sample_rate_hz not in cache:
            cache[sample_rate_hz] = self._render(sample_rate_hz)
        x, clipped = cache[sample_rate_hz]
        return np.repeat(x[:, None], channels, axis=1), clipped

    def _render(self, sample_rate_hz: float) -> tuple[np.ndarray, int]:
        from ..surface.straight import MirroredSurface
        from ..synthesis.acceleration import full_scale_of, tip_acceleration, to_full_scale

        surface = MirroredSurface(self.surface) if self.mirror else self.surface
        pressure = self.stroke.pressure if any(p is not None for p in self.stroke.pressure) else None
        sig = tip_acceleration(surface, self.stroke.t_s, self.stroke.x_m, self.stroke.y_m, pressure,
                               sample_rate_hz=sample_rate_hz, start_s=self.start_s, end_s=self.end_s)
        return to_full_scale(sig, self.gain, full_scale_of(self.surface))


def stroke_wav_source(timeline: DriveTimeline, stroke: Stroke, surface: SurfaceModel | None, drive: str = "profile", *,
                      synthetic: bool = False) -> DriveTimeline | StrokeAcceleration:
    """What a WAV of a stroke carries: the tip's acceleration for a surface profile's own
    drive, else the timeline's pulse train.  The CLI's ``export`` and the page's "Export
    this stroke" both ask here, so the two write the same file for the same stroke.

    Parameters
    ----------
    timeline : DriveTimeline
        :func:`~tactilize.export.run_stroke`'s result for ``stroke``.
    stroke : Stroke
        The pen samples (SI) the timeline was run from.
    surface : SurfaceModel or None
        The picture's surface; read when the timeline carries the surface rendering's events.
    drive : {"profile", "wire"}
        The timeline's drive asked for; the wire's drive stays a pulse train.
    synthetic : bool
        A synthetic stroke (timeline from stroke time 0, the picture mirrored
        beyond its edges); a recorded one starts at its first sample.
    """
    if surface is None or drive != "profile" or timeline.events is None:  # no crossings: the pulse train
        return timeline
    origin = 0.0 if synthetic else float(stroke.t_s[0])  # the timeline's t = 0 on the stroke's clock [s]
    return StrokeAcceleration(stroke, surface, origin, origin + float(timeline.end_s), mirror=synthetic)
