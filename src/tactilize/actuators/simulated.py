"""The default output: simulated SMA wires, each under its operating-point controller, in real time.

Every channel is a :class:`~tactilize.actuators.sma.WireModel` (the *plant*)
driven through a :class:`~tactilize.actuators.sma.WireController` exactly as the
tactile controller's firmware would drive a real wire: the controller decides
each pulse's width and the standby bias between pulses, reads the wire's
resistance and current after every piece of current flow (self-sensing), and
closes its loop once per pulse period.  Pulse starts follow the same
phase-continuous rules as the audio synthesiser
(:class:`~tactilize.synthesis.PulseScheduler`, here at 1 us resolution).

A background thread advances the plant by the wall-clock time elapsed, every
``tick_s``.  Recent traces (decimated to ``trace_rate_hz``) stay in ring buffers
for the web page; every pulse's own displacement peak is logged, so what the
finger gets can be read back (:meth:`SimulatedOutput.pulse_log`).

The plant may differ from what the controller was told (``plant_wire``,
``plant_circuit``): cells that sag, air that is warmer than configured.

Frames (:meth:`SimulatedOutput.play`): a regular train (a steady rendering's) plays from its Drive
by the scheduler; other events (docs/surfaces.md) replace those not yet fired, the controller holds
the operating point, each event one pulse, its heat its strength's place in the felt band at its
own interval, bounded by the running heat estimate (:class:`~.sma.heat.RunningHeat`).

Should the thread ever stop on an error, the output goes safe and says so: every
controller stops, :attr:`~SimulatedOutput.connected` turns False,
:attr:`~SimulatedOutput.fault` and :meth:`~SimulatedOutput.state` name the
failure, and :meth:`~SimulatedOutput.apply` refuses with it.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from ..errors import OutputError, check_finite
from ..drive import Drive
from .base import OutputBase
from .sma import Circuit, SafetyEnvelope, WireController, WireSpec, build_envelope
from .sma.controller import STATES, ControllerState
from .simulated_events import EventPlayer, WireChannel, relative_events

if TYPE_CHECKING:
    from ..surface.rendering import Frame

__all__ = ["SimulatedOutput"]

_US = 1_000_000  # schedule resolution: pulse edges at 1 us
#: Longest piece of constant current [us] per state: the controller reads the
#: wire after every piece, so warming bursts stop within a quarter millisecond.
_PIECE_US = {ControllerState.OFF: 20_000, ControllerState.STANDBY: 2_000, ControllerState.WARMING: 250,
             ControllerState.VIBRATING: 10_000}
_STATE_CODE = {name: i for i, name in enumerate(STATES)}
#: Longest simulated time [us] the real-time thread advances under one hold of the lock.
_SLICE_US = 5_000
#: Asked for once per piece of a warming burst (every 250 us): one shared value,
#: not a new validated Drive each time.
_OFF = Drive.off()


class SimulatedOutput(OutputBase):
    """Simulated SMA wires as an :class:`~tactilize.actuators.base.Output`.

    Parameters
    ----------
    wire : WireSpec or str
        The wire of every channel, as configured (a preset name or a spec).
    circuit : Circuit or str
        The driver circuit, as configured (``aa-resistor`` by default).
    channels : int
        Number of actuators (the pen has 2).
    envelope : SafetyEnvelope, optional
        Default: :func:`~tactilize.actuators.sma.build_envelope` of the wire and circuit.
    closed_loop : bool
        The controllers use the measured resistance and current (True).
    standby_s : float
        How long the standby bias holds a wire after the pen lifts or hovers [s].
    plant_wire, plant_circuit : optional
        The real wire and circuit when they differ from the configured ones
        (another ambient, sagging cells).
    trace_seconds : float
        Length of the kept traces [s].
    trace_rate_hz : float
        Trace points per second [Hz]; a pulse shorter than a trace step still
        marks its step with its current (the current trace is a max, not a mean).
    tick_s : float
        How often the thread advances the model [s].
    start : bool
        Start the real-time thread now; with False, call :meth:`advance` yourself
        (deterministic, for tests and offline use).
    clock : callable
        Monotonic clock in seconds (``time.monotonic``).
    """

    #: The profile's amplitude is felt strength on this output: the controller
    #: turns it into a position in the felt band (module docstring of
    #: :mod:`tactilize.actuators.sma.controller`), so both pins can play it.
    amplitude_is_intensity = False
    def __init__(
        self,
        wire: WireSpec | str | None = None,
        *,
        circuit: Circuit | str | None = None,
        channels: int = 2,
        envelope: SafetyEnvelope | None = None,
        closed_loop: bool = True,
        standby_s: float = 10.0,
        plant_wire: WireSpec | None = None,
        plant_circuit: Circuit | None = None,
        trace_seconds: float = 5.0,
        trace_rate_hz: float = 2000.0,
        tick_s: float = 0.02,
        start: bool = True,
        clock: Callable[[], float] = time.monotonic,
        **_ignored: Any,
    ) -> None:
        self.spec = WireSpec.resolve(wire)
        self.circuit = Circuit.resolve(circuit, self.spec)
        if not isinstance(channels, int) or channels < 1:
            raise OutputError("<simulated>", f"channels must be a positive integer, got {channels!r}")
        for name, v in (("trace_seconds", trace_seconds), ("trace_rate_hz", trace_rate_hz), ("tick_s", tick_s),
                        ("standby_s", standby_s)):
            check_finite(v, "<simulated>", what=name, error=OutputError, above=0.0)
        self.channels = channels
        self.envelope = envelope if envelope is not None else build_envelope(self.spec, self.circuit)
        self.tick_s = float(tick_s)
        self._bin_us = max(1, int(round(_US / trace_rate_hz)))
        self.trace_rate_hz = _US / self._bin_us
        self._bin_s = self._bin_us * 1e-6
        ps = plant_wire if plant_wire is not None else self.spec
        pc = plant_circuit if plant_circuit is not None else self.circuit
        self._chans = [
            WireChannel(ps, pc, WireController(self.spec, self.circuit, self.envelope, closed_loop=closed_loop,
                                            standby_s=standby_s))
            for _ in range(channels)
        ]
        self._drives = [Drive.off()] * channels
        #: Plays pulse events on the wires, and plans what a hand-over of them reports.
        self.event_player = EventPlayer(self._chans, self._piece, self._start_pulse, self._close_pulse)
        self._lock = threading.RLock()
        self._pending_lock = threading.Lock()  # held for microseconds only
        # (kind, drives, each channel's events relative to the hand-over [s] for "events")
        self._pending: list[tuple[str, list[Drive] | None, list[list[tuple[float, float]]] | None]] = []
        self._t_us = 0
        size = max(2, int(round(trace_seconds * self.trace_rate_hz)))
        self._size = size
        self._count = 0
        self._buf_t = np.zeros(size)
        self._buf = np.zeros((channels, 4, size))  # current, temperature, displacement, state
        self._clock = clock
        self._quiet = threading.Event()
        self._running = False
        self._thread: threading.Thread | None = None
        self._closed = False
        self._failure: str | None = None
        if start:
            self.start()

    # -- the Output interface

    @property
    def controllers(self) -> list[WireController]:
        """Each channel's controller (read-only use)."""
        return [ch.ctrl for ch in self._chans]

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        """Set every channel's texture drive; returns what each wire will get.

        The frequency is the drive's; the width is the controller's plan at the
        wire's state now (and within the envelope); ``amplitude`` 1.0 means the
        switch is fully on during each pulse.  An off drive lifts the pen:
        the wire goes to standby for ``standby_s``.
        """
        if self._closed:
            raise OutputError("<simulated>", "output is closed")
        if self._failure is not None:
            raise OutputError("<simulated>", self._failure)
        drives = self._check(channels)
        applied = []
        with self._lock:
            for ch, d in zip(self._chans, drives):
                if d.is_off:
                    applied.append(d)
                    continue
                plan = ch.ctrl.plan(d)
                clamped = d.clamped + tuple(n for n in plan.clamped if n not in d.clamped)
                out = d.replace(pulse_width_s=plan.pulse_width_s, amplitude=plan.level, clamped=clamped)
                applied.append(out)
        self._hand_over("apply", drives)
        self._drives = applied
        return applied

    def play(self, frame: Frame, now_s: float, channels: Sequence[Drive]) -> list[Drive]:
        """One frame (the Output interface): a regular train from its Drive, other events each a bounded pulse."""
        if frame.regular:
            return self.apply(channels)
        return self._play_events([frame.events] * self.channels, now_s, channels)

    def _play_events(self, channels: Sequence[Sequence[Any]], now_s: float, equivalent: Sequence[Drive]) -> list[Drive]:
        """Per channel, the pulse events to play from now on; replaces those not yet fired.
        Parameters
        ----------
        channels : sequence of sequence of PulseEvent
            Per channel, events with ``t_s`` on the stroke's clock.
        now_s : float
            The stroke-clock time [s] that is *now* (the newest pen sample's).
        equivalent : sequence of Drive
            Per channel, the steady drive of the window: the operating point the
            controller holds while the events play.

        Returns
        -------
        list of Drive
            What :meth:`apply` would give for ``equivalent``.  Stepped by :meth:`advance`
            (a stroke run offline, an export) that is its own plan; running in real time
            (:meth:`start`, the pen server) the simulation thread makes it when it takes the
            events, and a pen batch gets the plan of the operating point the wire holds (a
            tick old at most; the first batch after a steady drive, a lift or a stop its own).
        """
        if self._closed:
            raise OutputError("<simulated>", "output is closed")
        if self._failure is not None:
            raise OutputError("<simulated>", self._failure)
        drives = self._check(equivalent)
        applied = self.event_player.plan_to_show(drives)
        self._drives = applied
        rel = relative_events(channels, now_s, self.channels)
        with self._pending_lock:
            self._pending.append(("events", drives, rel))
        return applied

    def event_counts(self) -> list[dict[str, int]]:
        """Per channel: events fired as pulses, and events dropped (the wire was not yet in its
        band, or the running heat estimate left no room)."""
        with self._lock:
            return [{"fired": ch.events_fired, "dropped": ch.events_dropped} for ch in self._chans]

    def event_log(self, channel: int = 0) -> list[tuple[float, float]]:
        """Every recent pulse event of a channel whose period has ended: ``(start [s], rise [m])``,
        the pin's own travel during the pulse.  An irregular train has no period to compare a
        pulse with, so an event is followed when this rise reaches FOLLOW_THRESHOLD_M."""
        with self._lock:
            return list(self._chans[channel].event_log)

    def standby(self) -> None:
        """The pen is over the picture with nothing to render: hold every wire ready."""
        self._hand_over("standby", None)

    def stop(self) -> None:
        """Every channel fully off at once (pulses in progress complete, as on hardware)."""
        self._hand_over("stop", None)
        self._drives = [Drive.off()] * self.channels

    def _hand_over(self, kind: str, drives: list[Drive] | None) -> None:
        # A pen batch must never wait for a simulation tick: commands wait here
        # and the next advance takes them at the simulated instant it starts from.
        with self._pending_lock:
            self._pending.append((kind, drives, None))
            # Events after this are planned afresh (they follow a steady drive, a lift, a stop).
            self.event_player.handed_over()

    def _take_pending(self) -> None:
        with self._pending_lock:
            pending, self._pending = self._pending, []
            seen = self.event_player.handovers
        now = self._t_us * 1e-6
        taken: list[Drive] | None = None  # the newest events' operating point, if nothing came after them
        for kind, drives, rel in pending:
            if kind == "events" and drives is not None and rel is not None:
                self.event_player.take(drives, rel, self._t_us)
                taken = drives
                continue
            taken = None
            for c, ch in enumerate(self._chans):
                ch.events = None
                if kind == "stop":
                    ch.ctrl.stop()
                elif kind == "standby":
                    ch.ctrl.standby(now)
                elif drives is not None:
                    ch.ctrl.command(drives[c], now)
        if taken is not None and self.event_player.plan_on_take:
            # Planned for the page; dropped if a steady drive, a lift or a stop came meanwhile.
            shown = self.event_player.planned_for(taken)
            with self._pending_lock:
                if self.event_player.handovers == seen:
                    self.event_player.shown = self._drives = shown

    def close(self) -> None:
        """Stop, end the thread and wait for it."""
        self.stop()
        self._running = False
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(timeout=5.0)
        self._thread = None
        self._closed = True

    # -- running

    def start(self) -> None:
        """Start the real-time thread (once)."""
        if self._thread is not None:
            return
        self._running = True
        self.event_player.plan_on_take = True
        self._thread = threading.Thread(target=self._guarded_loop, name="tactilize-simulated-wire", daemon=True)
        self._thread.start()

    @property
    def connected(self) -> bool:
        """False once the simulation stopped on an error (:attr:`fault` says why)."""
        return self._failure is None

    @property
    def fault(self) -> str | None:
        """Why the simulation stopped, or None while it runs."""
        return self._failure

    def _guarded_loop(self) -> None:
        try:
            self._loop()
        except Exception as exc:  # whatever stopped the model, the output must not claim to run
            with self._lock:
                self._failure = f"the simulated wire stopped ({exc.__class__.__name__}: {exc}); its output is off"
                for ch in self._chans:
                    ch.ctrl.stop()
                self._drives = [Drive.off()] * self.channels
            self._running = False

    def after_batch(self) -> None:
        """Tell the simulation thread that a time-critical step just ended.

        The pen server calls this when a batch's drive has been sent; the thread,
        once its tick is due, steps the model in the gap before the next batch.
        """
        self._quiet.set()

    def _loop(self) -> None:
        last = self._clock()
        while self._running:
            time.sleep(self.tick_s)
            self._quiet.clear()
            self._quiet.wait(0.5 * self.tick_s)
            now = self._clock()
            # After a stall (suspended laptop) do not try to catch up minutes.
            todo_us = int(round(min(now - last, 1.0) * _US))
            last = now
            # In slices, each holding the lock on its own: a pen batch's apply()
            # waits for one slice (a fraction of a millisecond), not for a whole
            # tick (up to 14 ms measured on a loaded two-core machine).
            while todo_us > 0 and self._running:
                step = min(todo_us, _SLICE_US)
                self.advance(step / _US)
                todo_us -= step

    def advance(self, duration_s: float) -> None:
        """Advance every channel by ``duration_s`` [s] of simulated time."""
        n = int(round(duration_s * _US))
        if n <= 0:
            return
        with self._lock:
            self._take_pending()
            t0_us = self._t_us
            first = t0_us // self._bin_us + 1
            last = (t0_us + n) // self._bin_us
            bins_t = np.arange(first, last + 1) * self._bin_s
            cols = []
            for ch in self._chans:
                rec: list[float] = [ch.model.time_s, ch.model.temperature_c, ch.model.martensite_fraction]
                marks: list[tuple[int, int, float, int]] = []
                self._run_channel(ch, t0_us, n, rec, marks)
                if bins_t.size:
                    nodes = np.asarray(rec).reshape(-1, 3)
                    T = np.interp(bins_t, nodes[:, 0], nodes[:, 1])
                    xi = np.interp(bins_t, nodes[:, 0], nodes[:, 2])
                    cur = np.zeros(bins_t.size)
                    state = np.zeros(bins_t.size)
                    for s_us, e_us, amps, code in marks:
                        b0 = max(0, (t0_us + s_us) // self._bin_us + 1 - first)
                        b1 = min(bins_t.size - 1, (t0_us + e_us) // self._bin_us + 1 - first)
                        if b1 >= b0:
                            cur[b0 : b1 + 1] = np.maximum(cur[b0 : b1 + 1], amps)
                            state[b0 : b1 + 1] = code
                    cols.append((cur, T, ch.model.spec.displacement_m(xi), state))
            self._t_us += n
            if bins_t.size:
                self._push(bins_t, cols)

    def _piece(self, ch: WireChannel, dur_us: int, level: float, rec: list, marks: list, at_us: int) -> None:
        """Run one piece of constant switch level and let the controller read the wire."""
        if dur_us <= 0:
            return
        ch.model.run((dur_us * 1e-6,), (level,), record=rec)
        # Within a piece the temperature is monotone: its end holds the piece's peak.
        if ch.model.temperature_c > ch.peak_c:
            ch.peak_c = ch.model.temperature_c
        R = ch.model.resistance_ohm
        amps = ch.model.circuit.current_at(R)
        if level > 0:
            ch.ctrl.observe(R, amps, dur_us * 1e-6, ch.model.time_s)
        if ch.heat is not None:
            ch.heat.run(dur_us * 1e-6, level)
            if level > 0:
                ch.heat.anchor(ch.ctrl.martensite_fraction)
        marks.append((at_us, at_us + dur_us, level * amps, _STATE_CODE[ch.ctrl.state]))

    def _start_pulse(self, ch: WireChannel, s: int, width_us: int, step: int, t0_us: int, cursor: int,
                     rec: list, marks: list) -> int:
        """Switch a pulse of ``width_us`` [us] on at offset ``s`` of this step; what does not fit in
        the step is carried into the next.  Returns the step offset [us] where the pulse's part ends."""
        x0 = ch.model.displacement_m
        on = min(width_us, step - s)
        self._piece(ch, on, 1.0, rec, marks, cursor + s)
        ch.open_pulse = ((t0_us + cursor + s) * 1e-6, x0, ch.model.displacement_m)
        if width_us > on:
            ch.carry_us = width_us - on
        return s + on

    def _close_pulse(self, ch: WireChannel) -> None:
        """The next pulse starts (or the train stops): the last pulse's own peak is known."""
        if ch.open_pulse is not None:
            t, x0, x1 = ch.open_pulse
            x2 = ch.model.displacement_m
            ch.log.append((t, min(x1 - x0, x1 - x2), max(x0, x1, x2) - min(x0, x1, x2)))
            if ch.events is not None:
                ch.event_log.append((t, x1 - x0))
            ch.open_pulse = None

    def _run_channel(self, ch: WireChannel, t0_us: int, n: int, rec: list, marks: list) -> None:
        ctrl = ch.ctrl
        cursor = 0
        if ch.carry_us > 0:
            on = min(ch.carry_us, n)
            self._piece(ch, on, 1.0, rec, marks, 0)
            ch.carry_us -= on
            cursor = on
            if ch.carry_us == 0 and ch.open_pulse is not None:
                t, x0, _ = ch.open_pulse
                ch.open_pulse = (t, x0, ch.model.displacement_m)
        while cursor < n:
            step = min(n - cursor, _PIECE_US[ctrl.state])
            if ctrl.state == ControllerState.WARMING:
                # Each burst is short enough that the envelope's bound holds for it alone.
                step = max(1, min(step, int(ctrl.burst_s() * _US)))
            want = ctrl.drive if ctrl.pulses_on else _OFF
            if ch.events is not None:
                self.event_player.run_block(ch, EventPlayer.starts(ch, t0_us + cursor, step, want), step, t0_us,
                                           cursor, rec, marks)
                cursor += step
                continue
            if want != ch.scheduled:
                if want.is_off:
                    self._close_pulse(ch)
                    ch.sched.set_drive(want)
                else:
                    plan = ctrl.plan(want)
                    ch.sched.set_drive(Drive(want.pulse_frequency_hz, max(plan.pulse_width_s, 1e-6),
                                             regularity=want.regularity))
                ch.scheduled = want
            starts, _, _ = ch.sched.next_block(step)
            pos = 0
            for s in (starts if isinstance(starts, list) else starts.tolist()):
                if s < pos:  # a carried pulse still running
                    continue
                self._piece(ch, s - pos, ctrl.bias_level, rec, marks, cursor + pos)
                self._close_pulse(ch)
                ctrl.update(ch.model.time_s)
                plan = ctrl.plan(want)
                # Rounded down to the schedule's microsecond: never more heat than planned.
                width_us = int(plan.pulse_width_s * _US)
                ch.width_s, ch.current_a = width_us * 1e-6, ch.model.current_a
                if width_us <= 0:
                    pos = s
                    continue
                pos = self._start_pulse(ch, s, width_us, step, t0_us, cursor, rec, marks)
            self._piece(ch, step - pos, ctrl.bias_level if ctrl.state != ControllerState.WARMING or ctrl.warming_allowed() else 0.0,
                        rec, marks, cursor + pos)
            cursor += step
            if not starts:
                ctrl.update(ch.model.time_s)

    def _push(self, t: np.ndarray, cols: Sequence[tuple[np.ndarray, ...]]) -> None:
        m = t.size
        if m >= self._size:
            t = t[-self._size :]
            cols = [tuple(a[-self._size :] for a in col) for col in cols]
            m = self._size
        idx = (self._count + np.arange(m)) % self._size
        self._buf_t[idx] = t
        for c, col in enumerate(cols):
            for row, values in enumerate(col):
                self._buf[c, row, idx] = values
        self._count += m

    # -- reading

    @property
    def time_s(self) -> float:
        """Simulated time so far [s]."""
        return self._t_us * 1e-6

    def peak_temperature_c(self, channel: int = 0) -> float:
        """Highest temperature [deg C] a channel's wire reached since the last :meth:`reset_peak`."""
        with self._lock:
            return self._chans[channel].peak_c

    def reset_peak(self) -> None:
        """Start the peak temperatures afresh from the wires' temperatures now."""
        with self._lock:
            for ch in self._chans:
                ch.peak_c = ch.model.temperature_c

    def pulse_log(self, channel: int = 0) -> list[tuple[float, float, float]]:
        """Every recent pulse of a channel whose period has ended: ``(start [s],
        own rise [m], swing [m])``; the rise is how far the pulse's displacement
        peak stands above both its start and the next pulse's start."""
        with self._lock:
            return list(self._chans[channel].log)

    def traces(self, seconds: float = 2.0) -> dict[str, Any]:
        """The last ``seconds`` of traces as plain lists (JSON-ready).

        Returns
        -------
        dict
            ``time_s`` (simulated time [s]) and ``channels``: one dict per channel
            with ``current_a`` [A] (max over each trace step), ``temperature_c``
            [deg C], ``displacement_um`` [um], ``state`` (one of ``states``
            per step), plus ``drive`` (the drive applied).
        """
        with self._lock:
            m = min(self._count, self._size, max(0, int(round(seconds * self.trace_rate_hz))))
            idx = (self._count - m + np.arange(m)) % self._size
            out: dict[str, Any] = {"time_s": self._buf_t[idx].tolist(), "states": list(STATES), "channels": []}
            for c in range(self.channels):
                out["channels"].append(
                    {
                        "current_a": self._buf[c, 0, idx].tolist(),
                        "temperature_c": self._buf[c, 1, idx].tolist(),
                        "displacement_um": (self._buf[c, 2, idx] * 1e6).tolist(),
                        "state": [STATES[int(s)] for s in self._buf[c, 3, idx]],
                        "drive": self._drives[c].to_dict(),
                    }
                )
            return out

    def state(self) -> list[dict[str, Any]]:
        """Each channel now: controller state, temperature [deg C], martensite fraction,
        displacement [um], pulse current [mA] and width [ms], the drive."""
        with self._lock:
            return [
                {
                    "state": ch.ctrl.state if self._failure is None else "failed",
                    "temperature_c": ch.model.temperature_c,
                    "martensite_fraction": ch.model.martensite_fraction,
                    "displacement_um": ch.model.displacement_m * 1e6,
                    "current_ma": ch.current_a * 1e3,
                    "pulse_width_ms": ch.width_s * 1e3,
                    "bias_level": ch.ctrl.bias_level,
                    "drive": d.to_dict(),
                }
                for ch, d in zip(self._chans, self._drives)
            ]
