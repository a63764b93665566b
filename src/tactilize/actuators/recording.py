"""An output that only records what it is told: tests, offline renders and the server's last resort.

:class:`RecordingOutput` implements the Output interface
(:class:`~tactilize.actuators.base.Output`) without an actuator: every
:meth:`~RecordingOutput.apply` is kept, in order, with the channels it did not
name switched off, and every :meth:`~RecordingOutput.stop` is counted.  The pen
server falls back to it when the simulated wire is not available, the stroke
export renders through it when no wire is asked for, and tests read what a
renderer applied from it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

from ..drive import Drive
from .base import OutputBase

__all__ = ["RecordingOutput"]


@dataclass
class RecordingOutput(OutputBase):
    """Records every apply (one list of :class:`~tactilize.drive.Drive` per channel) and counts stops.

    Attributes
    ----------
    channels : int
        How many channels (2, the pen's two actuators).
    applied : list of list of Drive
        Every apply, in order, padded with :meth:`Drive.off` to ``channels``.
    stops : int
        How many times :meth:`stop` was called.
    """

    channels: int = 2
    applied: list[list[Drive]] = field(default_factory=list)
    stops: int = 0

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        """Record ``channels`` (the missing ones off) and return them as applied: no envelope acts."""
        drives = list(channels) + [Drive.off()] * (self.channels - len(channels))
        self.applied.append(drives)
        return drives

    def stop(self) -> None:
        """Count the stop; nothing runs."""
        self.stops += 1
