"""Pulse events: one per bump crossed, with a strength placed in the felt band.

:func:`place_events` turns crossings (times and prominences) into
:class:`PulseEvent` values by the rules of docs/surfaces.md ("What is rendered"):
strength is the prominence on a log scale between the picture's prominence
floor (0) and :data:`FULL_PROMINENCE` (1), scaled by pressure; clustered bumps
get weaker pulses; above :data:`RATE_ONLY_HZ` only the rate is rendered; no two
pulses are closer than :data:`MIN_INTERVAL_S`.  :func:`stroke_events` is a whole
stroke's events: the one whole-stroke path (:mod:`.playback`) through a surface rendering.

Units: SI (s, Hz); strength in [0, 1].
"""

from __future__ import annotations

import math
import statistics
from typing import Any, NamedTuple, Sequence

import numpy as np


__all__ = [
    "PulseEvent",
    "place_events",
    "strength_of",
    "strengths",
    "FULL_PROMINENCE",
    "full_prominence",
    "RATE_ONLY_HZ",
    "MAX_RATE_HZ",
    "MIN_INTERVAL_S",
    "CLUSTER_INTERVAL_S",
    "REFERENCE_PRESSURE",
    "pressure_scale",
    "event_statistics",
    "EventStatistics",
    "local_rate_hz",
]

#: Prominence [luminance units] that gets full strength: half the luminance range (a
#: surface in metres has its own, :func:`full_prominence`).
FULL_PROMINENCE = 0.5
#: Above this local rate [pulses/s] only the rate is rendered (every pulse there
#: gets its neighbourhood's median strength).
RATE_ONLY_HZ = 150.0
#: The wire's fastest pulse rate [Hz]: the paper's pen vibrates up to 300 Hz
#: (docs/references.md, section 1).
MAX_RATE_HZ = 300.0
#: No two pulses closer than this [s]; a closer crossing merges into the pulse before.
MIN_INTERVAL_S = 1.0 / MAX_RATE_HZ
#: A pulse closer than this [s] to the one before is a cluster: weaker in
#: proportion to its interval (the band's top falls as 1 / f above about 150 Hz
#: on the 75 um wire, docs/signals-and-wire.md).
CLUSTER_INTERVAL_S = 1.0 / RATE_ONLY_HZ
#: Pressure reported for a pressed button without a pressure sensor (Pointer Events):
#: full strength at or above it.
REFERENCE_PRESSURE = 0.5


class PulseEvent(NamedTuple):
    """One pulse to play.

    Attributes
    ----------
    t_s : float
        When [s], on the stroke's clock (the pen samples' timestamps).
    strength : float
        Place in the felt band at the local interval, 0 (least felt) .. 1 (most).
    clamped : tuple of str
        What changed it: ``"cluster"`` (weakened, too close to the one before),
        ``"rate_only"`` (strength of its neighbourhood), ``"merged"`` (a closer
        crossing was folded into it), ``"late"`` (found after its time, played at once).
    """

    t_s: float
    strength: float
    clamped: tuple[str, ...] = ()


def pressure_scale(pressure: float | None) -> float:
    """What pressure in [0, 1] multiplies strength by: 1 at :data:`REFERENCE_PRESSURE` or more,
    and without a pressure sensor (None)."""
    return 1.0 if pressure is None else min(1.0, max(0.0, float(pressure)) / REFERENCE_PRESSURE)


def full_prominence(surface: Any) -> float:
    """Prominence of full strength on ``surface``: its own when its heights are metres
    (``SurfaceModel.full_prominence``), else :data:`FULL_PROMINENCE`."""
    own = getattr(surface, "full_prominence", None)
    return FULL_PROMINENCE if own is None else float(own)


def strength_of(prominence: Any, floor: Any, pressure: float | None = None, full: float = FULL_PROMINENCE) -> np.ndarray:
    """Strength in [0, 1] of bumps of ``prominence`` on a picture with prominence ``floor``
    (log scale from the floor to ``full``, :func:`full_prominence`), scaled by ``pressure``."""
    p = np.broadcast_to(np.asarray(prominence, dtype=np.float64), np.shape(prominence))
    lo = np.broadcast_to(np.asarray(floor, dtype=np.float64), p.shape)
    return np.array(strengths(p.ravel().tolist(), lo.ravel().tolist(), pressure, full)).reshape(p.shape)


def strengths(prominence: Sequence[float], floor: Sequence[float], pressure: float | None = None,
              full: float = FULL_PROMINENCE) -> list[float]:
    """:func:`strength_of` on plain lists: a pen batch has a handful of bumps, where each
    NumPy call costs more than the arithmetic."""
    scale = pressure_scale(pressure)
    out = []
    for p, lo in zip(prominence, floor):
        span = math.log(max(full / lo, 1.0 + 1e-9))
        out.append(min(1.0, max(0.0, math.log(max(p, 1e-12) / lo) / span)) * scale)
    return out


def _local_rates(t: Sequence[float]) -> list[float]:
    n = len(t)
    if n < 2:
        return [0.0] * n
    span = [t[1] - t[0]] + [(t[i + 1] - t[i - 1]) / 2.0 for i in range(1, n - 1)] + [t[-1] - t[-2]]
    return [1.0 / max(d, 1e-12) if d > 0 else math.inf for d in span]


def local_rate_hz(t_s: np.ndarray) -> np.ndarray:
    """Crossing rate [1/s] at each crossing: two over the interval between its neighbours
    (one over the one interval at either end); 0 for a lone crossing."""
    return np.array(_local_rates(np.asarray(t_s, dtype=np.float64).tolist()), dtype=np.float64)


def place_events(
    t_s: Sequence[float] | np.ndarray,
    strength: Sequence[float] | np.ndarray,
    *,
    previous_t_s: float | None = None,
) -> list[PulseEvent]:
    """Pulse events for crossings at ``t_s`` [s] (increasing) of given ``strength``.

    Parameters
    ----------
    t_s : sequence of float
        Crossing times [s], increasing.
    strength : sequence of float
        Each crossing's strength in [0, 1] (:func:`strength_of`).
    previous_t_s : float, optional
        Time of the pulse already played before these [s] (its interval counts).

    Returns
    -------
    list of PulseEvent
    """
    # Plain Python in one pass: a pen batch places one crossing or two (docs/surfaces.md).
    t = [float(v) for v in t_s]
    s = [float(v) for v in strength]
    n = len(t)
    if n == 0:
        return []
    # Local rate above RATE_ONLY_HZ at each crossing (local_rate_hz, with the pulse before).
    u = t if previous_t_s is None else [float(previous_t_s)] + t
    m, off = len(u), len(u) - n
    fast = [False] * n
    if m > 1:
        for i in range(n):
            j = off + i
            d = u[1] - u[0] if j == 0 else u[-1] - u[-2] if j == m - 1 else (u[j + 1] - u[j - 1]) / 2.0
            fast[i] = d <= 0 or 1.0 / max(d, 1e-12) > RATE_ONLY_HZ
        if True in fast:
            # Only rate is rendered there: each pulse carries its neighbourhood's median.
            for i in range(n):
                if fast[i]:
                    s[i] = statistics.median(s[max(0, i - 3) : i + 4])
    out: list[PulseEvent] = []
    last = previous_t_s
    for i in range(n):
        ti, si = t[i], s[i]
        clamped: tuple[str, ...] = ("rate_only",) if fast[i] else ()
        if last is not None:
            gap = ti - last
            if gap < MIN_INTERVAL_S:
                if out and "merged" not in out[-1].clamped:
                    out[-1] = out[-1]._replace(clamped=out[-1].clamped + ("merged",))
                continue
            if gap < CLUSTER_INTERVAL_S and not fast[i]:
                si *= gap / CLUSTER_INTERVAL_S
                clamped += ("cluster",)
        out.append(PulseEvent(ti, si, clamped))
        last = ti
    return out


class EventStatistics(NamedTuple):
    """What a span of events amounts to: the one statistic every consumer reads.

    Attributes
    ----------
    pulses : int
        How many events.
    rate_hz : float
        Pulses per second: (n - 1) over the span from the first event to the last; where
        that span is empty (one event, or all at one instant) n over the span the events
        were gathered in (a lone event in a 150 ms window is 6.7 pulses/s: one pulse in
        that time), 0 when that span is not given.
    interval_cv : float
        Coefficient of variation of the intervals (0 below two intervals).
    strength : float
        Mean strength.
    clamped : tuple of str
        Every name that clamped any of them, sorted.
    """

    pulses: int
    rate_hz: float
    interval_cv: float
    strength: float
    clamped: tuple[str, ...]


def event_statistics(events: Sequence[PulseEvent], span_s: float | None = None) -> EventStatistics:
    """Rate [1/s], intervals' coefficient of variation, mean strength and clamps of ``events``.

    Parameters
    ----------
    events : sequence of PulseEvent
        Any order.
    span_s : float, optional
        The time the events were gathered in [s] (a window, a whole stroke): it gives the
        rate where the events themselves span no time (:class:`EventStatistics`).
    """
    n = len(events)
    if not n:
        return EventStatistics(0, 0.0, 0.0, 0.0, ())
    t = sorted(e.t_s for e in events)
    names: set[str] = set()
    for e in events:
        names.update(e.clamped)
    strength = math.fsum(e.strength for e in events) / n
    if n >= 2 and t[-1] > t[0]:
        iv = [b - a for a, b in zip(t, t[1:])]
        mean = math.fsum(iv) / len(iv)
        cv = math.sqrt(math.fsum((x - mean) ** 2 for x in iv) / len(iv)) / mean if len(iv) > 1 else 0.0
        rate = (n - 1) / (t[-1] - t[0])
    else:
        rate, cv = (n / span_s if span_s else 0.0), 0.0
    return EventStatistics(n, rate, cv, strength, tuple(sorted(names)))
