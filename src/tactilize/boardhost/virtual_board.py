"""A virtual-time RP2040 running the controller firmware, and the wire model as the judge.

The firmware (``tactilize/firmware/controller.py``, the file flashed on a board)
runs in-process with :class:`VirtualMachine` standing in for MicroPython's
``machine`` and its clock functions replaced by a simulated microsecond counter:
timers fire in order of their due time, the main loop's ``tick`` runs every
``POLL_MS``, a busy wait moves the clock, and the PWM slices make their pulses at
their wraps (a new compare latches at the wrap, as on the RP2040).  Nothing waits
on the wall clock, so seconds of frames at exact instants take milliseconds and
give the same result every run: ``tactilize profile report --serial`` and the
firmware's tests both play frames to it (the real-time emulator behind a
pseudo-terminal is :mod:`tactilize.boardhost.emulator`).

:func:`peak_on_wire` turns what a channel's pins did (pulses on the gate pin,
the standby bias PWM) into switch levels and runs them through the host's wire
model (:class:`~tactilize.actuators.sma.WireModel`) in the hottest design air.

The firmware is one module per process (like the one program on a board): a
:class:`VirtualBoard` patches its clock and ``machine`` while it lives and puts
them back on :meth:`VirtualBoard.close`; one board at a time, not thread-safe.
Every import of the firmware's host pieces is in this module.

Units: the board's microseconds where named ``_us``, else SI.
"""

from __future__ import annotations

import heapq
import itertools
import tempfile
from pathlib import Path
from types import ModuleType
from typing import Any, Callable

from ..actuators import frames as P
from ..actuators.sma import Circuit, WireModel, WireSpec, build_envelope

__all__ = ["VirtualMachine", "VirtualBoard", "firmware", "install", "peak_on_wire"]


def firmware() -> ModuleType:
    """The controller firmware module, loaded against the host's ``machine`` (once per process)."""
    from .emulator import load_firmware

    return load_firmware()


class VirtualMachine:
    """Just what the firmware uses of ``machine``, on a simulated clock [us]."""

    def __init__(self) -> None:
        self.now_us = 0
        self.ticks_offset_us = 0  # the ticks the board's clock read at now_us = 0
        self._timers: list[tuple[int, int, Any]] = []
        self._order = itertools.count()
        self.edges: dict[Any, list[tuple[int, int]]] = {}
        self.pulses: dict[Any, list[tuple[float, float]]] = {}  # PWM pulses: (start [us], width [us])
        self.bias: dict[Any, list[tuple[float, float]]] = {}  # (from [us], level) of a 20 kHz bias slice
        self.adc: dict[Any, Any] = {}
        self._pwms: list[Any] = []
        vm = self

        class Pin:
            IN, OUT, OPEN_DRAIN, PULL_UP, PULL_DOWN = 0, 1, 2, 1, 2

            def __init__(self, id, mode=-1, pull=-1, value=None):
                self.id = id
                self._mode = mode
                if mode == Pin.OUT:
                    vm._edge(id, 0 if value is None else int(bool(value)))

            def value(self, v=None):
                if v is None:
                    return 1 if self._mode == Pin.IN else vm._level(self.id)
                vm._edge(self.id, int(bool(v)))

        class PWM:
            def __init__(self, pin, freq=None, duty_u16=None):
                self.pin = pin.id
                self._hz = 1000
                self._next = float(vm.now_us)
                self._duty = 0  # latched [ns]
                self._pending = 0
                self._u16 = None
                vm._pwms.append(self)
                if freq is not None:
                    self.freq(freq)
                if duty_u16 is not None:
                    self.duty_u16(duty_u16)

            def _advance(self, until_us):
                period = 1e6 / self._hz
                while self._next <= until_us:
                    self._duty = self._pending
                    if self._duty > 0:
                        if self._hz >= 10000:  # the standby bias: a level, not pulses
                            pass
                        else:
                            vm.pulses.setdefault(self.pin, []).append((self._next, self._duty / 1e3))
                    self._next += period

            def freq(self, hz=None):
                if hz is None:
                    return self._hz
                if not isinstance(hz, int):
                    raise TypeError("can't convert float to int")
                self._advance(vm.now_us)
                self._hz = hz

            def duty_ns(self, ns=None):
                if ns is None:
                    return self._pending
                self._advance(vm.now_us)
                self._pending = max(0, min(int(ns), 1_000_000_000 // self._hz))
                if self._hz >= 10000:
                    vm.bias.setdefault(self.pin, []).append((vm.now_us, self._pending * self._hz / 1e9))

            def duty_u16(self, v=None):
                if v is None:
                    return int(self._pending * self._hz / 1e9 * 65535)
                self.duty_ns(int(v / 65535 * 1e9 / self._hz))

            def deinit(self):
                self._advance(vm.now_us)
                if self in vm._pwms:
                    vm._pwms.remove(self)
                if self._hz >= 10000:
                    vm.bias.setdefault(self.pin, []).append((vm.now_us, 0.0))

        class ADC:
            def __init__(self, pin):
                self.id = pin.id if hasattr(pin, "id") else pin

            def read_u16(self):
                src = vm.adc.get(self.id, 0)
                return max(0, min(65535, int(src() if callable(src) else src)))

        class Timer:
            ONE_SHOT, PERIODIC = 0, 1

            def __init__(self, id=-1, mode=1, period=None, freq=None, callback=None):
                self.period_us = int(round(1e6 / freq)) if freq is not None else int(period) * 1000
                self.period_us = max(1, self.period_us)
                self.mode, self.callback, self.alive = mode, callback, True
                vm._schedule(vm.now_us + self.period_us, self)

            def deinit(self):
                self.alive = False

        class WDT:
            def __init__(self, id=0, timeout=5000):
                pass

            def feed(self):
                pass

        self.Pin, self.PWM, self.ADC, self.Timer, self.WDT = Pin, PWM, ADC, Timer, WDT

    # -- machine's module functions
    def disable_irq(self):
        return 0

    def enable_irq(self, state=0):
        return None

    def reset_cause(self):
        return 1

    # -- the clock the firmware reads: MicroPython's ticks wrap at 2^30
    TICKS_PERIOD = 1 << 30

    def ticks_us(self) -> int:
        return (self.now_us + self.ticks_offset_us) & (self.TICKS_PERIOD - 1)

    def ticks_ms(self) -> int:
        return ((self.now_us + self.ticks_offset_us) // 1000) & (self.TICKS_PERIOD - 1)

    @classmethod
    def ticks_diff(cls, a: int, b: int) -> int:
        half = cls.TICKS_PERIOD >> 1
        return ((a - b + half) & (cls.TICKS_PERIOD - 1)) - half

    @classmethod
    def ticks_add(cls, a: int, b: int) -> int:
        if not -(cls.TICKS_PERIOD >> 1) <= b < (cls.TICKS_PERIOD >> 1):
            raise OverflowError("ticks interval overflow")
        return (a + b) & (cls.TICKS_PERIOD - 1)

    def sleep_us(self, us: int) -> None:
        self.now_us += max(0, int(us))

    # -- bookkeeping
    def _edge(self, pin, level: int) -> None:
        self.edges.setdefault(pin, []).append((self.now_us, level))

    def _level(self, pin) -> int:
        e = self.edges.get(pin)
        return e[-1][1] if e else 0

    def _schedule(self, due: int, timer) -> None:
        heapq.heappush(self._timers, (due, next(self._order), timer))

    def run_until(self, t_us: int, tick: Callable[[], None], poll_us: int) -> None:
        """Fire every timer due before ``t_us`` and call ``tick`` every ``poll_us``."""
        next_tick = (self.now_us // poll_us + 1) * poll_us
        while True:
            due = self._timers[0][0] if self._timers else None
            if due is not None and due <= min(next_tick, t_us):
                _, _, timer = heapq.heappop(self._timers)
                if not timer.alive:
                    continue
                self.now_us = max(self.now_us, due)
                if timer.mode == timer.PERIODIC:
                    self._schedule(due + timer.period_us, timer)
                else:
                    timer.alive = False
                timer.callback(timer)
                continue
            if next_tick <= t_us:
                self.now_us = max(self.now_us, next_tick)
                tick()
                next_tick += poll_us
                continue
            self.now_us = max(self.now_us, t_us)
            return

    def finish(self) -> None:
        for pwm in list(self._pwms):
            pwm._advance(self.now_us)

    def channel_levels(self, pin, bias_pin, end_us: int) -> tuple[list[float], list[float]]:
        """(durations [s], switch levels) of one channel's gate up to ``end_us``."""
        on: list[tuple[float, float]] = list(self.pulses.get(pin, []))
        rise = None
        for t, level in self.edges.get(pin, []):
            if level and rise is None:
                rise = t
            elif not level and rise is not None:
                on.append((float(rise), float(t - rise)))
                rise = None
        on.sort()
        bias = sorted(self.bias.get(bias_pin, []), key=lambda e: e[0])  # stable: the last write at an instant wins
        # Break points: pulse edges and bias changes.
        points = {0.0, float(end_us)}
        for s, w in on:
            points.update((s, s + w))
        points.update(float(t) for t, _ in bias)
        grid = sorted(p for p in points if 0.0 <= p <= end_us)
        durs, levels = [], []
        bi, b = 0, 0.0
        pi = 0
        for a, z in zip(grid, grid[1:]):
            while bi < len(bias) and bias[bi][0] <= a:
                b = bias[bi][1]
                bi += 1
            while pi < len(on) and on[pi][0] + on[pi][1] <= a:
                pi += 1
            inside = pi < len(on) and on[pi][0] <= a < on[pi][0] + on[pi][1]
            durs.append((z - a) * 1e-6)
            levels.append(1.0 if inside else b)
        return durs, levels


def peak_on_wire(durations_s: Any, levels: Any, circuit: str | Circuit = "aa-resistor",
                 spec: WireSpec | None = None, start_c: float | None = None, air_c: float | None = None) -> float:
    """The wire model's highest temperature [deg C] under a switch schedule, in
    air at ``air_c`` (default the envelope's hottest design air), from that air
    or ``start_c``."""
    spec = WireSpec.resolve(spec)
    env = build_envelope(spec, circuit)
    air = env.design_ambient_c if air_c is None else air_c
    model = WireModel(spec.replace(ambient_c=air), Circuit.resolve(circuit, spec),
                      temperature_c=air if start_c is None else start_c)
    edges: list = []
    model.run(durations_s, levels, edges=edges)
    return max([model.initial_temperature_c] + [T for T, _ in edges])


SetAttr = Callable[[Any, str, Any], None]


def install(fw: ModuleType, set_attr: SetAttr) -> VirtualMachine:
    """Run the loaded firmware module ``fw`` on a fresh virtual board; every patch
    goes through ``set_attr(obj, name, value)`` (a test's ``monkeypatch.setattr``,
    or :class:`VirtualBoard`'s, which undoes them on close)."""
    vm = VirtualMachine()
    set_attr(fw, "machine", vm)
    for name, fn in (("_ticks_us", vm.ticks_us), ("_ticks_ms", vm.ticks_ms), ("_ticks_diff", vm.ticks_diff),
                     ("_ticks_add", vm.ticks_add), ("_sleep_us", vm.sleep_us)):
        set_attr(fw, name, fn)
        set_attr(fw.F, name, fn)
    for module in (getattr(fw, "C", None), getattr(fw, "H", None)):
        if module is not None and hasattr(module, "machine"):
            set_attr(module, "machine", vm)
    return vm


class _Patches:
    """setattr that remembers the old values, to put them back."""

    def __init__(self) -> None:
        self._old: list[tuple[Any, str, Any]] = []

    def set(self, obj: Any, name: str, value: Any) -> None:
        self._old.append((obj, name, getattr(obj, name)))
        setattr(obj, name, value)

    def undo(self) -> None:
        while self._old:
            obj, name, value = self._old.pop()
            setattr(obj, name, value)


class VirtualBoard:
    """The firmware on a virtual board, its wire and circuit stored as a board stores them.

    Parameters
    ----------
    store : str or Path, optional
        The board's file system (its config is written there); a temporary
        directory, removed on :meth:`close`, by default.
    circuit : str or Circuit
        The circuit the board's config is written for (the paper's wire).
    set_attr : callable, optional
        How to patch the firmware module (``monkeypatch.setattr`` in tests);
        by default the patches are undone on :meth:`close`.
    after_watchdog_reset : bool
        The board has just started (after a watchdog reset, or any other): its
        heat estimates start at the budget, as every board's do.  By default
        the board has been idle long enough for them to have cooled, as the
        wire the judge starts from (``Controller(assume_cold=True)``).
    """

    def __init__(self, store: str | Path | None = None, circuit: str | Circuit = "aa-resistor", *,
                 set_attr: SetAttr | None = None, after_watchdog_reset: bool = False,
                 ticks_start_us: int = 0, design_air_c: float | None = None) -> None:
        from .board import board_config_text

        self.fw = fw = firmware()
        self._patches = _Patches()
        self._tmp = tempfile.TemporaryDirectory(prefix="tactilize-board-") if store is None else None
        root = Path(self._tmp.name if self._tmp is not None else str(store))
        self.vm = install(fw, set_attr or self._patches.set)
        self.vm.ticks_offset_us = int(ticks_start_us)
        if after_watchdog_reset:
            setattr(self.vm, "WDT_RESET", 3)
            setattr(self.vm, "reset_cause", lambda: 3)
        (root / fw.W.CONFIG_FILE).write_text(board_config_text(None, circuit, design_air_c))
        self.sent: list[bytes] = []
        self.ctl = fw.Controller(self.sent.append, store=str(root) + "/", assume_cold=not after_watchdog_reset)
        self.circuit = circuit
        self.seq = 0

    def close(self) -> None:
        """Put the firmware module back as it was; remove the temporary store."""
        self._patches.undo()
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> VirtualBoard:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def now_s(self) -> float:
        """The board's clock [s]."""
        return self.vm.now_us / 1e6

    def send(self, command: Any, payload: bytes = b"") -> None:
        """A frame as the host writes it, received at once."""
        self.seq = (self.seq + 1) & 0xFFFF
        self.ctl.feed(P.encode_frame(self.seq, command, payload))

    def set(self, channel: int, f_hz: float, w_s: float, amp: float = 1.0, regularity: float | None = None) -> None:
        self.send(P.Command.SET, P.encode_set_channel(channel, f_hz, w_s, amp, regularity))

    def until(self, t_s: float) -> None:
        """Run the board until its clock reads ``t_s`` [s]."""
        self.vm.run_until(int(round(t_s * 1e6)), self.ctl.tick, self.fw.POLL_MS * 1000)

    def replies(self) -> list:
        """The frames the board wrote since the last call."""
        frames = P.FrameDecoder().feed(b"".join(self.sent))
        self.sent.clear()
        return frames

    def peak_c(self, channel: int = 0, *, air_c: float | None = None, start_c: float | None = None) -> float:
        """The wire model's peak [deg C] under what the channel's pins did so far,
        in air at ``air_c`` (default the design air), from ``start_c`` (default that air)."""
        self.vm.finish()
        pins = (self.fw.CHANNEL_PINS[channel], self.fw.BIAS_PINS[channel])
        durs, levels = self.vm.channel_levels(*pins, self.vm.now_us)
        return peak_on_wire(durs, levels, self.circuit, start_c=start_c, air_c=air_c)

    def pulse_starts_us(self, channel: int = 0) -> list[float]:
        """When each pulse on the channel's gate pin began [us, board clock], in order:
        the soft-timer and scheduled pulses (rising edges) and the PWM slice's."""
        self.vm.finish()
        pin = self.fw.CHANNEL_PINS[channel]
        soft = [float(t) for t, level in self.vm.edges.get(pin, []) if level]
        return sorted(soft + [s for s, w in self.vm.pulses.get(pin, []) if w > 0])

    def pulse_count(self, channel: int = 0) -> int:
        return len(self.pulse_starts_us(channel))
