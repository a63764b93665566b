"""The steady Drive that stands for the events of the next window, for outputs that cannot play events.

Serial boards, the audio output (until part 2) and the exports take one
:class:`~tactilize.drive.Drive` per channel.  :func:`equivalent_drive` gives them
the statistically equivalent one (docs/surfaces.md, "How events replace the
steady Drive"): its frequency the events' local rate, its regularity from their
intervals' coefficient of variation (inverting the jitter law of
:mod:`tactilize.synthesis`), its strength their mean strength, its width the
profile's width law at that strength.  The SMA outputs also command their
operating point with it while they play the events themselves.

Units: SI (s, Hz).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

from ..drive import Drive
from .events import EventStatistics, PulseEvent, event_statistics

__all__ = ["equivalent_drive", "window_statistics", "drive_of_statistics", "regularity_of_cv", "WINDOW_S"]

#: Events this far behind the newest sample still count towards the window [s].
WINDOW_S = 0.15
#: Interval CV of a train jittered at full depth (JITTER_MAX_PERIODS / sqrt(6)).
_FULL_JITTER_CV = 0.6 / math.sqrt(6.0)


def regularity_of_cv(cv: float) -> float:
    """The ``Drive.regularity`` whose jittered train has intervals of coefficient of variation ``cv``."""
    return float(min(1.0, max(0.0, 1.0 - cv / _FULL_JITTER_CV)))


def window_statistics(events: Sequence[PulseEvent], now_s: float, window_s: float = WINDOW_S) -> EventStatistics:
    """:func:`~.events.event_statistics` of the events from ``now_s - window_s`` [s] on (all
    those ahead included); a lone event there is a rate of ``1 / window_s``."""
    since = now_s - window_s
    return event_statistics([e for e in events if e.t_s >= since], window_s)


def drive_of_statistics(stats: EventStatistics, profile: Any = None) -> Drive:
    """The steady drive of a window's :func:`window_statistics` (see :func:`equivalent_drive`)."""
    if not stats.pulses:
        return Drive.off()
    strength = stats.strength
    width_law = getattr(profile, "width", None)
    width = float(width_law(strength)) if width_law is not None else 4e-4 * strength
    width = max(width, 2e-5)
    d = Drive(float(stats.rate_hz), width, 1.0, stats.clamped, min(1.0, max(0.0, strength)),
              regularity_of_cv(stats.interval_cv))
    limits = getattr(profile, "limits", None)
    return limits.apply(d) if limits is not None else d


def equivalent_drive(
    events: Sequence[PulseEvent],
    now_s: float,
    profile: Any = None,
    *,
    window_s: float = WINDOW_S,
) -> Drive:
    """The steady drive of the events around ``now_s`` [s] (the last ``window_s`` and all ahead).

    Parameters
    ----------
    events : sequence of PulseEvent
        Recent and scheduled events, any order.
    now_s : float
        The newest sample's time [s] on the stroke's clock.
    profile : Profile, optional
        Its width law turns strength into a width and its limits apply; without
        one the width is 0.4 ms x strength (the paper's reading of h) and no limits act.

    Returns
    -------
    Drive
        Off when no event is in the window.
    """
    return drive_of_statistics(window_statistics(events, now_s, window_s), profile)
