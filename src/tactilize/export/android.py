"""Android vibration that follows a stroke: API 36 envelopes and the ``createWaveform`` fallback.

One JSON document a developer pastes in, the same for every rendering: the
events of the stroke (a stroke's bumps, a steady drive's pulses), as
compositions of primitives where they come at least 20 ms apart and API 36
envelopes where they come closer, with the ``createWaveform`` fallback
(:mod:`.android_events` has its keys; docs/references.md, section 6 (Android
waveform) and (Android envelopes)).

References
----------
.. [1] docs/references.md, section 6 (Android waveform).
.. [2] docs/references.md, section 6 (Android envelopes).
"""

from __future__ import annotations

from typing import Any

from ..drive import Drive
from .android_envelopes import ANDROID_LIMITS
from .android_events import android_events_document
from .timeline import CONTROL_STEP_S, DriveTimeline

__all__ = ["android_document", "android_waveform", "ANDROID_LIMITS"]

def android_document(tl: DriveTimeline, kind: str = "profile", channel: int = 0, step_s: float = CONTROL_STEP_S) -> dict[str, Any]:
    """The Android document of one channel of a timeline: its events (:mod:`.android_events`)."""
    return android_events_document(tl, kind, channel, step_s)


def android_waveform(drive: Drive, duration_s: float = 2.0) -> dict[str, Any]:
    """The Android document of one steady drive held for ``duration_s`` [s]."""
    return android_document(DriveTimeline.steady(drive, duration_s))
