"""The simulated wire's pulse events: handed over, scheduled and played one bounded pulse each.

Part of :mod:`tactilize.actuators.simulated` (kept apart to keep each module short).
:class:`WireChannel` is one simulated wire; :class:`EventPlayer`, owned by
:class:`~tactilize.actuators.simulated.SimulatedOutput`, holds what playing events
needs besides the wires: the plan a hand-over reports, and whether the simulation
thread or the hand-over makes it.  :meth:`EventPlayer.take` turns a
:meth:`~tactilize.actuators.simulated.SimulatedOutput.play` call into each channel's
queue of starts at the simulated instant it is taken, replacing what is not yet due;
:meth:`EventPlayer.starts` takes the events of one block; :meth:`EventPlayer.run_block`
plays them, the controller's bias between pulses, each pulse planned from its strength
at the shorter of its two intervals and bounded by the channel's running heat estimate
(docs/surfaces.md).

Units: SI; times in the simulation's microseconds where named ``_us``.
"""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING, Callable, Sequence

from ..drive import Drive
from ..synthesis import PulseScheduler
from .sma import Circuit, WireController, WireModel, WireSpec
from .sma.heat import RunningHeat

if TYPE_CHECKING:
    from ..surface.events import PulseEvent

__all__ = ["WireChannel", "EventPlayer", "relative_events"]

_US = 1_000_000
_OFF = Drive.off()

#: Runs one piece of constant switch level on a wire: (channel, duration [us], level,
#: record, marks, offset [us] in the block).
Piece = Callable[["WireChannel", int, float, list, list, int], None]
#: Switches a pulse on: (channel, offset [us], width [us], step [us], block start [us],
#: cursor [us], record, marks); returns the offset [us] where its part in the step ends.
StartPulse = Callable[["WireChannel", int, int, int, int, int, list, list], int]
#: Ends the pulse being followed on a channel.
ClosePulse = Callable[["WireChannel"], None]


class WireChannel:
    """One wire: plant, controller, pulse schedule, and the pulse being followed."""

    def __init__(self, plant_spec: WireSpec, plant_circuit: Circuit, ctrl: WireController) -> None:
        self.model = WireModel(plant_spec, plant_circuit)
        self.ctrl = ctrl
        self.sched = PulseScheduler(_US)
        self.scheduled = Drive.off()
        self.carry_us = 0  # rest of a pulse that runs into the next block
        self.open_pulse: tuple[float, float, float] | None = None  # (t_s, x_start, x_end)
        self.log: deque[tuple[float, float, float]] = deque(maxlen=4096)  # (t_s, rise_m, swing_m)
        self.width_s = 0.0
        self.current_a = 0.0
        self.peak_c = self.model.temperature_c
        #: Pulse events still to fire (simulated start [us], strength), in order; None: steady drive.
        self.events: deque[tuple[int, float]] | None = None
        self.last_event_us: int | None = None
        self.heat: RunningHeat | None = None
        self.events_fired = 0
        self.events_dropped = 0
        #: Pulses of events: (start [s], rise during the pulse [m]).
        self.event_log: deque[tuple[float, float]] = deque(maxlen=4096)

    def planned(self, d: Drive) -> Drive:
        """What the controller's plan gives ``d`` at the wire's state now."""
        # Read without the simulation's lock: a pen batch would wait for a whole slice
        # of it (up to 5 ms) every batch.  plan() only reads a few floats of the
        # controller, each read whole; what it returns is for the page, and every
        # pulse is planned again, under the lock, when it is played.
        plan = self.ctrl.plan(d)
        clamped = d.clamped + tuple(n for n in plan.clamped if n not in d.clamped)
        return d.replace(pulse_width_s=plan.pulse_width_s, amplitude=plan.level, clamped=clamped)


class EventPlayer:
    """Plays pulse events on a simulated output's wires, and plans what a hand-over reports.

    Every pulse is planned when it plays; the plan of the window's equivalent drive is what
    a hand-over reports.  Stepped by hand (offline) each hand-over makes its own plan.
    Running in real time (:attr:`plan_on_take`) the simulation thread makes it when it takes
    the events, so a pen batch does not plan it again: a batch gets the newest plan, the first
    batch after a steady drive, a lift or a stop its own.

    Parameters
    ----------
    channels : sequence of WireChannel
        The output's wires.
    piece, start_pulse, close_pulse : callable
        The output's steps of a wire's simulation (:data:`Piece`, :data:`StartPulse`,
        :data:`ClosePulse`).
    """

    def __init__(self, channels: Sequence[WireChannel], piece: Piece, start_pulse: StartPulse,
                 close_pulse: ClosePulse) -> None:
        self.channels = list(channels)
        self._piece, self._start_pulse, self._close_pulse = piece, start_pulse, close_pulse
        #: The plan of the operating point the newest events came with (the page shows it).
        self.shown: list[Drive] | None = None
        #: The simulation thread plans the operating point of the events it takes (running in
        #: real time: a pen batch is spared it); otherwise each hand-over plans its own.
        self.plan_on_take = False
        #: Steady drives, lifts and stops handed over so far.
        self.handovers = 0

    def planned_for(self, drives: Sequence[Drive]) -> list[Drive]:
        """What the output's ``apply`` would give for the equivalent ``drives`` (both pins
        usually get the same drive: planned once)."""
        applied: list[Drive] = []
        for ch, d in zip(self.channels, drives):
            same = applied and d is drives[len(applied) - 1]
            applied.append(d if d.is_off else applied[-1] if same else ch.planned(d))
        return applied

    def plan_to_show(self, drives: Sequence[Drive]) -> list[Drive]:
        """What a hand-over of events reports: its own plan when stepped by hand, the newest
        plan the simulation thread made when running in real time (the first hand-over after
        a steady drive, a lift or a stop plans its own)."""
        applied = self.shown if self.plan_on_take else None
        if applied is None:
            applied = self.planned_for(drives)
            if self.plan_on_take:
                self.shown = applied
        return applied

    def handed_over(self) -> None:
        """A steady drive, a lift or a stop was handed over: events after it are planned afresh.
        (Called under the output's hand-over lock.)"""
        self.shown = None
        self.handovers += 1

    def take(self, drives: Sequence[Drive], rel: Sequence[Sequence[tuple[float, float]]], now_us: int) -> None:
        """Events handed over, taken at the simulated instant ``now_us`` [us]: relative times
        [s] become starts; ``drives`` is the operating point each controller holds meanwhile."""
        now_s = now_us * 1e-6
        for ch, d, evs in zip(self.channels, drives, rel):
            ch.ctrl.command(d, now_s)
            if ch.events is None:
                ch.events = deque()
                ch.heat = ch.heat or RunningHeat(ch.ctrl.envelope)
                if not ch.scheduled.is_off:
                    self._close_pulse(ch)
                    ch.sched.set_drive(_OFF)
                    ch.scheduled = _OFF
            # Replace what is not yet due; an event due by now was fired on the stroke's side.
            while ch.events and ch.events[-1][0] > now_us:
                ch.events.pop()
            # Pulses are at least 1/300 s apart: one within a millisecond of a kept
            # (due) event is that event sent again.
            after = ch.events[-1][0] + 1000 if ch.events else -1
            for dt, strength in evs:
                at = now_us + max(0, int(round(dt * _US)))
                if at >= after:
                    ch.events.append((at, strength))

    @staticmethod
    def starts(ch: WireChannel, at_us: int, step: int, want: Drive) -> list[tuple[int, Drive]]:
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

    def run_block(self, ch: WireChannel, starts: list[tuple[int, Drive]], step: int, t0_us: int, cursor: int,
                  rec: list, marks: list) -> None:
        """One block of an events channel: bias between pulses, one bounded pulse per event."""
        ctrl = ch.ctrl
        heat = ch.heat
        assert heat is not None  # set when the channel took its first events
        pos = 0
        for s, drive in starts:
            if s < pos:  # a carried pulse still running
                ch.events_dropped += 1
                continue
            self._piece(ch, s - pos, ctrl.bias_level, rec, marks, cursor + pos)
            self._close_pulse(ch)
            ctrl.update(ch.model.time_s)
            plan = ctrl.plan(drive)
            width_s = min(plan.pulse_width_s, heat.max_pulse_s())
            width_us = int(width_s * _US)
            ch.width_s, ch.current_a = width_us * 1e-6, ch.model.current_a
            pos = s
            if width_us <= 0:
                ch.events_dropped += 1
                continue
            ch.events_fired += 1
            pos = self._start_pulse(ch, s, width_us, step, t0_us, cursor, rec, marks)
        level = ctrl.bias_level if ctrl.state != "warming" or ctrl.warming_allowed() else 0.0
        self._piece(ch, step - pos, level, rec, marks, cursor + pos)
        if not starts:
            ctrl.update(ch.model.time_s)


def relative_events(channels: Sequence[Sequence[PulseEvent]], now_s: float, n: int) -> list[list[tuple[float, float]]]:
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
