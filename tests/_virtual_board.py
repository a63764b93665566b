"""A virtual-time RP2040 for the firmware, and the wire model as the judge.

The firmware (``tactilize/firmware/controller.py``) runs in-process with this
module's :class:`VirtualMachine` standing in for MicroPython's ``machine`` and
its clock functions replaced by a simulated microsecond counter: timers fire in
order of their due time, the main loop's ``tick`` runs every ``POLL_MS``, a busy
wait moves the clock, and the PWM slices make their pulses at their wraps (a new
compare latches at the wrap, as on the RP2040).  Nothing waits on the wall
clock, so a test can drive seconds of frames at exact instants in milliseconds.

:func:`peak_on_wire` turns what a channel's pins did (pulses on the gate pin,
the standby bias PWM) into switch levels and runs them through the host's wire
model (:class:`~tactilize.actuators.sma.WireModel`) in the hottest design air.
"""

from __future__ import annotations

import heapq
import itertools
from typing import Any, Callable

from tactilize.actuators import frames as P
from tactilize.actuators.sma import Circuit, WireModel, WireSpec, build_envelope
from tactilize.firmware import tactile_wire as W
from tactilize.boardhost.board import board_config_text
from tactilize.boardhost.emulator import load_firmware

fw = load_firmware()
PIN0, PIN1 = fw.CHANNEL_PINS
BIAS0, BIAS1 = fw.BIAS_PINS


class VirtualMachine:
    """Just what the firmware uses of ``machine``, on a simulated clock [us]."""

    def __init__(self) -> None:
        self.now_us = 0
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
            def __init__(self, pin):
                self.pin = pin.id
                self._hz = 1000
                self._next = float(vm.now_us)
                self._duty = 0  # latched [ns]
                self._pending = 0
                self._u16 = None
                vm._pwms.append(self)

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

    # -- the clock the firmware reads
    def ticks_us(self) -> int:
        return self.now_us

    def ticks_ms(self) -> int:
        return self.now_us // 1000

    @staticmethod
    def ticks_diff(a: int, b: int) -> int:
        return a - b

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


def peak_on_wire(durations_s, levels, circuit: str | Circuit = "aa-resistor", spec: WireSpec | None = None,
                 start_c: float | None = None) -> float:
    """The wire model's highest temperature [deg C] under a switch schedule, in
    the envelope's hottest design air (from that air, or ``start_c``)."""
    spec = WireSpec.resolve(spec)
    env = build_envelope(spec, circuit)
    air = env.design_ambient_c
    model = WireModel(spec.replace(ambient_c=air), Circuit.resolve(circuit, spec),
                      temperature_c=air if start_c is None else start_c)
    edges: list = []
    model.run(durations_s, levels, edges=edges)
    return max([model.initial_temperature_c] + [T for T, _ in edges])


def install(fw, monkeypatch) -> VirtualMachine:
    """Run the loaded firmware module ``fw`` on a fresh virtual board."""
    vm = VirtualMachine()
    monkeypatch.setattr(fw, "machine", vm)
    for name, fn in (("_ticks_us", vm.ticks_us), ("_ticks_ms", vm.ticks_ms), ("_ticks_diff", vm.ticks_diff),
                     ("_sleep_us", vm.sleep_us)):
        monkeypatch.setattr(fw, name, fn)
        monkeypatch.setattr(fw.F, name, fn)
    for module in (getattr(fw, "C", None), getattr(fw, "H", None)):
        if module is not None and hasattr(module, "machine"):
            monkeypatch.setattr(module, "machine", vm)
    return vm


class Board:
    """The firmware on a virtual board, with its store in ``tmp``."""

    def __init__(self, monkeypatch, tmp, circuit="aa-resistor", after_watchdog_reset=False):
        self.vm = install(fw, monkeypatch)
        if after_watchdog_reset:
            self.vm.WDT_RESET = 3
            self.vm.reset_cause = lambda: 3
        (tmp / W.CONFIG_FILE).write_text(board_config_text(None, circuit))
        self.sent: list[bytes] = []
        self.ctl = fw.Controller(self.sent.append, store=str(tmp) + "/")
        self.circuit = circuit
        self.seq = 0

    def send(self, command, payload=b""):
        self.seq += 1
        self.ctl.feed(P.encode_frame(self.seq, command, payload))

    def set(self, channel, f_hz, w_s, amp=1.0, regularity=None):
        self.send(P.Command.SET, P.encode_set_channel(channel, f_hz, w_s, amp, regularity))

    def until(self, t_s):
        self.vm.run_until(int(round(t_s * 1e6)), self.ctl.tick, fw.POLL_MS * 1000)

    def replies(self):
        frames = P.FrameDecoder().feed(b"".join(self.sent))
        self.sent.clear()
        return frames

    def peak_c(self, channel=0):
        self.vm.finish()
        pins = ((PIN0, BIAS0), (PIN1, BIAS1))[channel]
        durs, levels = self.vm.channel_levels(*pins, self.vm.now_us)
        return peak_on_wire(durs, levels, self.circuit)

    def pulse_count(self, channel=0):
        self.vm.finish()
        pin = fw.CHANNEL_PINS[channel]
        soft = sum(1 for _, level in self.vm.edges.get(pin, []) if level)
        return soft + sum(1 for _, w in self.vm.pulses.get(pin, []) if w > 0)
