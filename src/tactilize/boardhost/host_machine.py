"""MicroPython's ``machine`` module in real time, on the chip model, so the
controller firmware runs unchanged on the host.

The emulator puts this module into ``sys.modules["machine"]`` before it imports
``controller.py``.  Its classes are :mod:`tactilize.boardhost.rp2040`'s (the one
model of the RP2040 under MicroPython, also behind the virtual board and the
MicroPython tests' stand-in) on a chip whose clock is ``time.perf_counter``; a
:class:`Timer` runs its callback on a thread, like the soft IRQ of a board, and
the watchdog resets the chip from a thread when it is not fed.  What a real board
would show on its pins is recorded, so tests and the emulator see what the
outputs do rather than what the firmware claims:

- :func:`pin_state` gives a pin's present state (GPIO level, or PWM frequency
  and high time);
- :data:`events` keeps a log of ``(time_s, kind, pin_id, detail)``;
- :func:`add_listener` calls a function on every change;
- :func:`pwm_pulses` gives a pin's exact high pulses from the chip's history.

All state is module-global, like the one board it stands for; call
:func:`reset` between independent uses.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from typing import Any, Callable

from . import rp2040, rp2040_machine

__all__ = [
    "Pin", "PWM", "ADC", "Timer", "WDT", "freq", "reset", "pin_state", "events", "add_listener", "remove_listener",
    "pwm_pulses", "chip", "reset_cause", "disable_irq", "enable_irq", "mem32", "ticks_us", "ticks_ms",
]

_lock = threading.RLock()
#: the one chip, on perf_counter [us]
chip = rp2040.Chip(lambda: time.perf_counter() * 1e6)
chip.lock = _lock  # type: ignore[assignment]
_machine = rp2040_machine.Machine(chip)
_pins: dict[Any, dict[str, Any]] = {}
_rise_s: dict[Any, float] = {}
_listeners: list[Callable[[float, str, Any, dict[str, Any]], None]] = []
#: change log: (time [s, perf_counter], kind, pin id, detail)
events: deque = deque(maxlen=10_000)
#: perf_counter [s] of every watchdog reset
resets: list[float] = []
WDT_RESET = rp2040.WDT_RESET
PWRON_RESET = rp2040.PWRON_RESET
mem32 = _machine.mem32
ticks_us = _machine.ticks_us
ticks_ms = _machine.ticks_ms


def _on_chip(t_us: float, kind: str, pin_id: Any, detail: dict[str, Any]) -> None:
    t = t_us / 1e6
    with _lock:
        if kind == "reset":
            # every pad back to a floating input: the gates' pull-downs hold them low
            for p in list(_pins):
                _pins[p] = {"mode": "gpio", "value": 0}
            _rise_s.clear()
            targets = [(p, {"mode": "gpio", "value": 0}) for p in _pins]
        else:
            state = _pins.setdefault(pin_id, {"mode": "gpio", "value": 0})
            detail = dict(detail)
            if kind == "gpio":
                state.pop("frequency_hz", None)
                state["duty_ns"] = 0
                if detail.get("value") and pin_id not in _rise_s:
                    _rise_s[pin_id] = t
                elif not detail.get("value") and pin_id in _rise_s:
                    detail["last_pulse_s"] = t - _rise_s.pop(pin_id)
            elif kind == "pwm" and detail.pop("stopped", False):
                detail = {"mode": "pwm", "duty_ns": 0}
            state.update(detail)
            targets = [(pin_id, detail)]
        for p, d in targets:
            events.append((t, "reset" if kind == "reset" else kind, p, dict(d)))
        listeners = list(_listeners)
    for p, d in targets:
        for fn in listeners:
            fn(t, "reset" if kind == "reset" else kind, p, dict(d))


chip.listeners.append(_on_chip)


def reset() -> None:
    """Forget every pin, event and listener: a fresh board (a power-on reset)."""
    with _lock:
        chip.reset("power")
        chip.history.clear()
        chip.reset_log.clear()
        chip.adc_inputs.clear()
        chip.gpio_inputs.clear()
        chip.adc_gain = 1.0
        _pins.clear()
        _rise_s.clear()
        events.clear()
        _listeners.clear()
        for w in list(_watchdogs):
            w._stop.set()
        _watchdogs.clear()
        resets.clear()


def pin_state(pin_id: Any) -> dict[str, Any]:
    """A copy of a pin's present state.

    Returns
    -------
    dict
        ``mode`` ("gpio" or "pwm": the pad's function), ``value`` (GPIO level), and
        for PWM ``frequency_hz`` and ``duty_ns`` (high time per period [ns], 0 once
        the slice is stopped); ``last_pulse_s`` is the length of the last high
        pulse made by toggling the pin [s], when there was one.
    """
    with _lock:
        return dict(_pins.get(pin_id, {"mode": "gpio", "value": 0}))


def add_listener(fn: Callable[[float, str, Any, dict[str, Any]], None]) -> None:
    """Call ``fn(time_s, kind, pin_id, detail)`` on every pin change."""
    with _lock:
        _listeners.append(fn)


def remove_listener(fn: Callable) -> None:
    with _lock:
        if fn in _listeners:
            _listeners.remove(fn)


def freq(hz: int | None = None) -> int:
    """The system clock [Hz] (read only here)."""
    return rp2040.SYS_CLK_HZ


def reset_cause() -> int:
    return _machine.reset_cause()


def pwm_pulses(pin_id: Any, until_s: float | None = None) -> list[tuple[float, float]]:
    """The pad's complete high pulses, from the chip's register writes and the
    RP2040's timing (docs/references.md, section 10 (PWM slice)).

    Returns
    -------
    list of (start [s, perf_counter], width [s])
    """
    with _lock:
        got = chip.pulses_us(pin_id, None if until_s is None else until_s * 1e6)
    return [(s / 1e6, w / 1e6) for s, w in got]


Pin = _machine.Pin
PWM = _machine.PWM


class ADC(_machine.ADC):  # type: ignore[name-defined]
    """An ADC input: ``read_u16`` converts what a test puts in :attr:`sources`
    (gpio 26..29 -> the true reading, a number or a function of no arguments)."""

    #: gpio -> the true read_u16 (the chip's inputs)
    sources: dict[Any, Any] = chip.adc_inputs


#: How early a timer's thread wakes to spin to its due time [s].
_TIMER_SPIN_S = 0.005


class _ThreadScheduler:
    """The chip's soft timers on host threads: each armed timer waits on a thread
    of its own for its due instant, then runs its callback."""

    def arm(self, timer: Any, due_us: float) -> None:
        stop = threading.Event()
        timer._stop = stop
        th = threading.Thread(target=self._run, args=(timer, due_us / 1e6, stop), daemon=True)
        timer._thread = th
        th.start()

    def cancel(self, timer: Any) -> None:
        stop = getattr(timer, "_stop", None)
        if stop is not None:
            stop.set()
        th = getattr(timer, "_thread", None)
        timer._thread = None
        if th is not None and th is not threading.current_thread():
            th.join(timeout=1.0)

    @staticmethod
    def _run(timer: Any, next_t: float, stop: threading.Event) -> None:
        while not stop.wait(max(0.0, next_t - _TIMER_SPIN_S - time.perf_counter())):
            # A board's timer fires on its microsecond; a host thread wakes when
            # the scheduler lets it, so it wakes early and spins the rest.
            while time.perf_counter() < next_t and not stop.is_set():
                time.sleep(0)
            if stop.is_set():
                return
            if timer.callback is not None:
                timer.callback(timer)
            if timer.mode == Timer.ONE_SHOT:
                return
            # a periodic alarm is rescheduled from its previous due instant
            next_t += timer.period_us / 1e6


chip.scheduler = _ThreadScheduler()


class Timer(_machine.Timer):  # type: ignore[name-defined]
    """A soft timer (``machine.Timer``) whose callback runs on a host thread."""

    @property
    def period_ms(self) -> float:
        """The armed interval [ms] (the rp2 port's rounding)."""
        return self.period_us / 1e3


_watchdogs: list["WDT"] = []


class WDT(_machine.WDT):  # type: ignore[name-defined]
    """The hardware watchdog (``machine.WDT``).  When it is not fed for ``timeout``
    ms it resets the chip (a watchdog reset: every PWM slice and pad back to its
    reset state, the gates pulled low), recorded in :data:`resets`."""

    def __init__(self, id: int = 0, timeout: int = 5000) -> None:
        super().__init__(id, timeout)
        self.last_feed_s = time.perf_counter()
        self._stop = threading.Event()
        with _lock:
            _watchdogs.append(self)
        threading.Thread(target=self._watch, daemon=True).start()

    def feed(self) -> None:
        super().feed()
        self.last_feed_s = time.perf_counter()

    def _watch(self) -> None:
        while not self._stop.wait(0.002):
            with _lock:
                if chip.wdt_expired():
                    chip.reset("watchdog")
                    resets.append(time.perf_counter())
                    self._stop.set()


#: what disable_irq holds on the host: the timers' threads and the main loop
#: share the firmware's heat estimate, as IRQs and the main loop do on a board
_irq = threading.RLock()


def disable_irq() -> bool:
    _irq.acquire()
    return True


def enable_irq(state: bool = True) -> None:
    _irq.release()
