"""The simulated wire's pulse events: handed over, scheduled and played one bounded pulse each.

Part of :mod:`tactilize.actuators.simulated` (kept apart to keep each module short):
:func:`take_events` turns a :meth:`~tactilize.actuators.simulated.SimulatedOutput.play`
call into each channel's queue of starts at the simulated instant it is taken,
replacing what is not yet due; :func:`event_starts` takes the events of one
block; :func:`run_event_block` plays them, the controller's bias between pulses,
each pulse planned from its strength at the shorter of its two intervals and
bounded by the channel's running heat estimate (docs/surfaces.md).

Units: SI; times in the simulation's microseconds where named ``_us``.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

from ..drive import Drive
from .sma.heat import RunningHeat

__all__ = ["take_events", "event_starts", "run_event_block", "planned_for_events", "plan_to_show", "show_taken_plan",
           "relative_events"]

_US = 1_000_000
_OFF = Drive.off()
def planned_for_events(out: Any, drives: list[Drive]) -> list[Drive]:
    """What :meth:`~tactilize.actuators.simulated.SimulatedOutput.apply` would give for the
    equivalent ``drives`` (both pins usually get the same drive: planned once).

    Every pulse is planned afresh when it plays; this plan is what a hand-over of events
    reports (:func:`plan_to_show` says when it is made)."""
    applied: list[Drive] = []
    for ch, d in zip(out._chans, drives):
        same = applied and d is drives[len(applied) - 1]
        applied.append(d if d.is_off else applied[-1] if same else out._planned(ch, d))
    return applied


def plan_to_show(out: Any, drives: list[Drive]) -> list[Drive]:
    """What a hand-over of events reports: its own plan when the simulation is stepped by hand
    (offline), the newest plan the simulation thread made when it runs in real time (the first
    hand-over after a steady drive, a lift or a stop plans its own)."""
    applied = out._events_shown if out._plan_on_take else None
    if applied is None:
        applied = planned_for_events(out, drives)
        out._drives = applied
        if out._plan_on_take:
            out._events_shown = applied
    return applied


def show_taken_plan(out: Any, taken: list[Drive], seen: int) -> None:
    """The simulation thread took events with operating point ``taken``: plan it for the page,
    unless a steady drive, a lift or a stop was handed over since (``seen`` hand-overs then)."""
    shown = planned_for_events(out, taken)
    with out._pending_lock:
        if out._handovers == seen:
            out._events_shown = out._drives = shown


def relative_events(channels: Any, now_s: float, n: int) -> list[list[tuple[float, float]]]:
    """Per channel of ``n``, ``(t - now_s [s], strength)`` of each event; a list handed to
    several channels (both pins play the same) is converted once."""
    rel: list[list[tuple[float, float]]] = []
    for i, evs in enumerate(channels):
        if i and evs is channels[i - 1]:
            rel.append(rel[-1])
        else:
            rel.append([(float(e.t_s) - now_s, float(e.strength)) for e in evs])
    rel += [[] for _ in range(n - len(rel))]
    return rel


def take_events(out: Any, payload: tuple[list[Drive], list[list[tuple[float, float]]]], now: float) -> None:
    """Events handed over at the simulated instant ``now`` [s]: relative times become starts."""
    drives, rel = payload
    for ch, d, evs in zip(out._chans, drives, rel):
        ch.ctrl.command(d, now)
        if ch.events is None:
            ch.events = deque()
            ch.heat = ch.heat or RunningHeat(ch.ctrl.envelope)
            if not ch.scheduled.is_off:
                out._close_pulse(ch)
                ch.sched.set_drive(_OFF)
                ch.scheduled = _OFF
        # Replace what is not yet due; an event due by now was fired on the stroke's side.
        while ch.events and ch.events[-1][0] > out._t_us:
            ch.events.pop()
        # Pulses are at least 1/300 s apart: one within a millisecond of a kept
        # (due) event is that event sent again.
        after = ch.events[-1][0] + 1000 if ch.events else -1
        for dt, strength in evs:
            at = out._t_us + max(0, int(round(dt * _US)))
            if at >= after:
                ch.events.append((at, strength))


def event_starts(ch: Any, at_us: int, step: int, want: Drive) -> list[tuple[int, Drive]]:
    """The events due in [at_us, at_us + step) as (offset [us], the drive of that one pulse)."""
    out: list[tuple[int, Drive]] = []
    q = ch.events
    end = at_us + step
    while q and q[0][0] < end:
        t_us, strength = q.popleft()
        if want.is_off:
            ch.events_dropped += 1  # not yet in the band (warming) or off
            continue
        prev = ch.last_event_us
        ch.last_event_us = t_us
        # The band of the shorter of its two intervals: a pulse must also leave the
        # wire time to relax before the next one.
        gap = min(t_us - prev if prev is not None else math.inf, q[0][0] - t_us if q else math.inf)
        rate = want.pulse_frequency_hz if gap == math.inf else _US / max(1, gap)
        rate = min(300.0, max(1.0, rate))
        out.append((max(0, t_us - at_us), want.replace(pulse_frequency_hz=rate, strength=strength)))
    return out


def run_event_block(out: Any, ch: Any, starts: list[tuple[int, Drive]], step: int, t0_us: int, cursor: int,
                rec: list, marks: list) -> None:
    """One block of an events channel: bias between pulses, one bounded pulse per event."""
    ctrl = ch.ctrl
    pos = 0
    for s, drive in starts:
        if s < pos:  # a carried pulse still running
            ch.events_dropped += 1
            continue
        out._piece(ch, s - pos, ctrl.bias_level, rec, marks, cursor + pos)
        out._close_pulse(ch)
        ctrl.update(ch.model.time_s)
        plan = ctrl.plan(drive)
        width_s = min(plan.pulse_width_s, ch.heat.max_pulse_s())
        width_us = int(width_s * _US)
        ch.width_s, ch.current_a = width_us * 1e-6, ch.model.current_a
        pos = s
        if width_us <= 0:
            ch.events_dropped += 1
            continue
        ch.events_fired += 1
        pos = out._start_pulse(ch, s, width_us, step, t0_us, cursor, rec, marks)
    level = ctrl.bias_level if ctrl.state != "warming" or ctrl.warming_allowed() else 0.0
    out._piece(ch, step - pos, level, rec, marks, cursor + pos)
    if not starts:
        ctrl.update(ch.model.time_s)
