"""Pulse events for a version 4 board: each one planned, timed on the board's clock and given an id.

Part of :mod:`tactilize.actuators.serial` (kept apart to keep each module short).
:func:`plan_pulses` turns a channel's :class:`~tactilize.surface.events.PulseEvent`
list into (board time [us], width [us]) pairs: each pulse's width is its strength
placed in the wire's felt band at the shorter of its two intervals (as the
simulated wire does, docs/surfaces.md), through the safety envelope and the
board's hard limits; its time is the stroke time mapped onto the host's clock at
the call and from there onto the board's (:class:`~tactilize.actuators.clock_sync.ClockSync`).
:class:`EventSender` makes the EVENTS frames, keeping each pulse's id from frame
to frame: a pulse sent again (the next batch, a resend) within :data:`MATCH_US`
of where it was keeps its id, so the board never plays it twice.
:func:`board_limits` is the controller's own limits (frequency, width, duty) read
from its STATUS reply, applied to a drive.

Units: SI; the board's microseconds where named ``_us``.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Sequence

from ..drive import Drive
from . import frames as P

__all__ = ["EventSender", "plan_pulses", "board_limits", "MATCH_US"]

#: A pulse within this of one sent before is that pulse again [us] (pulses are at
#: least 1/300 s apart, so two different ones never are).
MATCH_US = 3000.0
#: A pulse within this after one sent before and already played [us] is that pulse
#: again, found a little later by a later batch (1/150 s: closer pulses are a
#: cluster the rendering weakens anyway, docs/surfaces.md).
MATCH_PLAYED_US = 1e6 / 150
#: The band's lowest and highest pulse rate [Hz] for the interval rule.
_RATE_HZ = (1.0, 300.0)
#: Pulses remembered per channel for their ids.
_HISTORY = 32


def board_limits(drive: Drive, status: P.ControllerStatus) -> Drive:
    """``drive`` within the controller's hard limits, each limit that acted named
    ``controller:<limit>``.  Frequency and width are exact in wire units; the duty
    is a product of two rounded integers, so it stays 10 ppm inside."""
    if drive.is_off:
        return drive
    f, w = drive.pulse_frequency_hz, drive.pulse_width_s
    names: list[str] = []
    if f > status.max_frequency_hz:
        f, names = status.max_frequency_hz, names + ["max_frequency_hz"]
    elif f < status.min_frequency_hz:
        f, names = status.min_frequency_hz, names + ["min_frequency_hz"]
    if w > status.max_pulse_width_s:
        w, names = status.max_pulse_width_s, names + ["max_pulse_width_s"]
    elif w < status.min_pulse_width_s:
        w, names = status.min_pulse_width_s, names + ["min_pulse_width_s"]
    duty = status.max_duty_ratio * (1 - 1e-5)
    if f * w > duty:
        w, names = duty / f, names + ["max_duty_ratio"]
    if not names:
        return drive
    extra = tuple(f"controller:{n}" for n in names if f"controller:{n}" not in drive.clamped)
    return drive.replace(pulse_frequency_hz=f, pulse_width_s=w, clamped=drive.clamped + extra)


def plan_pulses(events: Sequence[Any], stroke_zero_s: float, host_now_s: float, board_us: Callable[[float], float],
                operating: Drive, make_safe: Callable[[Drive], Drive],
                width_us: tuple[int, int]) -> list[tuple[float, int]]:
    """(board time [us, unwrapped], width [us]) of each event.

    Parameters
    ----------
    events : sequence of PulseEvent
        Times ``t_s`` on the stroke's clock, in order.
    stroke_zero_s : float
        The host time [s] of stroke time 0 (:class:`~tactilize.surface.clock.StrokeClock`).
    host_now_s : float
        The host's clock now [s]: a pulse due before it plays at once (the
        stroke hands over only what is not yet fired, a late crossing at its
        newest sample's time).
    board_us : callable
        Host time [s] -> the board's clock [us].
    operating : Drive
        The channel's equivalent drive (the operating point); a pulse is this at
        its own rate and strength.
    make_safe : callable
        Drive -> the drive as the board may play it (felt band, envelope, hard limits).
    width_us : (int, int)
        The board's narrowest and widest pulse [us].
    """
    ts = [float(e.t_s) for e in events]
    base = operating if not operating.is_off else Drive(_RATE_HZ[0], 1e-4)
    out: list[tuple[float, int]] = []
    for k, e in enumerate(events):
        gap = min(ts[k] - ts[k - 1] if k else math.inf, ts[k + 1] - ts[k] if k + 1 < len(ts) else math.inf)
        rate = base.pulse_frequency_hz if gap == math.inf else 1.0 / max(gap, 1e-6)
        rate = min(_RATE_HZ[1], max(_RATE_HZ[0], rate))
        d = make_safe(base.replace(pulse_frequency_hz=rate, strength=min(1.0, max(0.0, float(e.strength)))))
        if d.is_off:
            continue
        w = min(width_us[1], max(width_us[0], int(round(d.pulse_width_s * 1e6))))
        out.append((board_us(max(stroke_zero_s + ts[k], host_now_s)), w))
    return out


class EventSender:
    """The EVENTS frames of each channel, with ids kept from frame to frame."""

    def __init__(self, channels: int) -> None:
        self._next = [0] * channels
        # Per channel, the (board time [us], id) of the pulses sent lately, and
        # whether the last frame left any pulse scheduled.
        self._sent: list[list[tuple[float, int]]] = [[] for _ in range(channels)]
        self._live = [False] * channels

    def forget(self) -> None:
        """The board forgot its schedules (stop, a train, a reconnect); ids go on."""
        self._live = [False] * len(self._live)

    def payload(self, channel: int, pulses: Sequence[tuple[float, int]], force: bool = False,
                now_us: float | None = None) -> bytes | None:
        """The EVENTS payload replacing ``channel``'s schedule with ``pulses``
        ((board time [us], width [us]), in order; at most :data:`~tactilize.actuators.frames.MAX_EVENTS`
        within 65 ms of the first are sent, the rest go with a later frame); None
        when there is nothing to send or withdraw (unless ``force``).  ``now_us``: the
        board's clock now, so a pulse already played is recognised further off."""
        prev = self._sent[channel]
        if not pulses and not self._live[channel] and not force:
            return None
        base = int(math.floor(pulses[0][0])) if pulses else 0
        entries, sent, used = [], [], set()
        for t, width in pulses[: P.MAX_EVENTS]:
            off = int(round(t - base))
            if off > 0xFFFF:
                break
            near = [(abs(tp - t), i) for tp, i in prev if i not in used and (
                abs(tp - t) <= MATCH_US or (now_us is not None and tp <= now_us and 0 <= t - tp <= MATCH_PLAYED_US))]
            eid = min(near)[1] if near else None
            if eid is None:
                eid = self._next[channel]
                self._next[channel] = (eid + 1) & 0xFFFF
            used.add(eid)
            entries.append((eid, off, width))
            sent.append((t, eid))
        keep = [(tp, i) for tp, i in prev if i not in used]
        self._sent[channel] = (keep + sent)[-_HISTORY:]
        self._live[channel] = bool(sent)
        return P.encode_events(channel, base, entries)
