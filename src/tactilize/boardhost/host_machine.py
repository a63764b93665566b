"""A small stand-in for MicroPython's ``machine`` module, so the controller
firmware runs unchanged on the host.

The emulator puts this module into ``sys.modules["machine"]`` before it imports
``controller.py``.  It implements just what the firmware uses (``Pin``, ``PWM``,
``Timer``, ``WDT``, ``freq``, ``reset_cause``, ``disable_irq``) with the RP2040's semantics, and it records every
change a real board would show on its pins, so tests and the emulator can see
what the outputs do rather than what the firmware claims:

- :func:`pin_state` gives a pin's present state (GPIO level, or PWM frequency
  and high time);
- :data:`events` keeps a log of ``(time_s, kind, pin_id, detail)``;
- :func:`add_listener` calls a function on every change.

A periodic :class:`Timer` really runs its callback on a thread, like the soft
IRQ of a board, so pulse trains made by toggling a pin are observable too (the
pin records the length of its last high pulse).

All state is module-global, like the one board it stands for; call
:func:`reset` between independent uses.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from typing import Any, Callable

__all__ = [
    "Pin", "PWM", "ADC", "Timer", "WDT", "freq", "reset", "pin_state", "events", "add_listener", "remove_listener",
    "pwm_pulses",
]

#: RP2040 default system clock [Hz]
_SYSTEM_CLOCK_HZ = 125_000_000
# The RP2040 PWM counter is 16 bits with an 8.4 fixed-point divider of at most
# 255 + 15/16: below this frequency a slice cannot produce the period.
_PWM_MIN_FREQUENCY_HZ = _SYSTEM_CLOCK_HZ / (65536 * (255 + 15 / 16))

_lock = threading.RLock()
_pins: dict[Any, dict[str, Any]] = {}
_listeners: list[Callable[[float, str, Any, dict[str, Any]], None]] = []
#: change log: (time [s, perf_counter], kind, pin id, detail)
events: deque = deque(maxlen=10_000)


def _record(kind: str, pin_id: Any, **detail: Any) -> None:
    t = time.perf_counter()
    with _lock:
        state = _pins.setdefault(pin_id, {"mode": "gpio", "value": 0})
        state.update(detail)
        events.append((t, kind, pin_id, dict(detail)))
        listeners = list(_listeners)
    for fn in listeners:
        fn(t, kind, pin_id, dict(detail))


def reset() -> None:
    """Forget every pin, event and listener (a fresh board)."""
    with _lock:
        _pins.clear()
        events.clear()
        _listeners.clear()
        _live_pwms.clear()
        _pwm_logs.clear()
        Pin.inputs.clear()
        ADC.sources.clear()
        for w in list(_watchdogs):
            w._stop.set()
        _watchdogs.clear()
        resets.clear()


def pin_state(pin_id: Any) -> dict[str, Any]:
    """A copy of a pin's present state.

    Returns
    -------
    dict
        ``mode`` ("gpio" or "pwm"), ``value`` (GPIO level), and for PWM
        ``frequency_hz`` and ``duty_ns`` (high time per period [ns]);
        ``last_pulse_s`` is the length of the last high pulse made by toggling
        the pin [s], when there was one.
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
    return _SYSTEM_CLOCK_HZ


def reset_cause() -> int:
    return 1


class Pin:
    """A GPIO pin (``machine.Pin``); ids are ints or names such as ``"LED"``."""

    IN = 0
    OUT = 1
    OPEN_DRAIN = 2
    PULL_UP = 1
    PULL_DOWN = 2

    #: levels of pins configured as inputs, settable by tests (``Pin.inputs[15] = 0``)
    inputs: dict[Any, int] = {}

    def __init__(self, id: Any, mode: int = -1, pull: int = -1, *, value: int | None = None) -> None:
        self.id = id
        self._t_high: float | None = None
        self.init(mode, pull, value=value)

    def init(self, mode: int = -1, pull: int = -1, *, value: int | None = None) -> None:
        self._mode = mode
        self._pull = pull
        if mode == Pin.OUT:
            # Re-initialising a pin as an output takes it back from a PWM slice.
            _record("gpio", self.id, mode="gpio", value=int(bool(value)) if value is not None else 0)

    def value(self, v: int | None = None) -> int | None:
        if v is None:
            if self._mode == Pin.IN:
                default = 1 if self._pull == Pin.PULL_UP else 0
                return Pin.inputs.get(self.id, default)
            return pin_state(self.id).get("value", 0)
        level = int(bool(v))
        now = time.perf_counter()
        detail: dict[str, Any] = {"mode": "gpio", "value": level}
        if level and self._t_high is None:
            self._t_high = now
        elif not level and self._t_high is not None:
            detail["last_pulse_s"] = now - self._t_high
            self._t_high = None
        _record("gpio", self.id, **detail)
        return None

    def on(self) -> None:
        self.value(1)

    def off(self) -> None:
        self.value(0)

    def __call__(self, v: int | None = None) -> int | None:
        return self.value(v)


def _slice_of(pin_id: Any) -> Any:
    """The RP2040 PWM slice of a GPIO: its two outputs (A and B) share one counter,
    so one frequency."""
    return (pin_id >> 1) & 7 if isinstance(pin_id, int) else pin_id


_live_pwms: list["PWM"] = []
#: per pin: the RP2040 slice's register writes, (time [s], name, value): "start"
#: (div16, top, cc), "div" (takes effect at once), "top" and "cc" (at the next wrap)
_pwm_logs: dict[Any, list[tuple[float, str, Any]]] = {}


def _div_top(hz: int) -> tuple[int, int]:
    """Divider (in 1/16) and TOP for a frequency [Hz]: the smallest divider whose
    period fits the 16-bit counter (the RP2040's fractional divider)."""
    counts16 = _SYSTEM_CLOCK_HZ * 16 / hz
    div16 = max(16, -(-int(counts16) // 65536))
    top = max(1, int(round(counts16 / div16)) - 1)
    return div16, top


def _log(pin_id: Any, name: str, value: Any) -> None:
    with _lock:
        _pwm_logs.setdefault(pin_id, []).append((time.perf_counter(), name, value))


def pwm_pulses(pin_id: Any, until_s: float | None = None) -> list[tuple[float, float]]:
    """The high pulses a slice output made, from its register writes and the
    RP2040's timing: the divider applies at once, TOP and compare at the wrap.

    Returns
    -------
    list of (start [s, perf_counter], width [s])
        Complete pulses only.
    """
    with _lock:
        log = list(_pwm_logs.get(pin_id, ()))
    if not log:
        return []
    end = time.perf_counter() if until_s is None else until_s
    t, _, (div, top, cc) = log[0]
    pend: dict[str, int] = {}
    c, i = 0.0, 1
    high_at: float | None = None
    out: list[tuple[float, float]] = []
    while t < end:
        while i < len(log) and log[i][0] <= t:
            _, name, v = log[i]
            i += 1
            if name == "div":
                div = v
            elif name == "stop":
                return out
            else:
                pend[name] = v
        t_event = log[i][0] if i < len(log) else end
        rate = _SYSTEM_CLOCK_HZ * 16 / div  # counts per second
        falls = high_at is not None and c < cc <= top
        target = cc if falls else top + 1
        t_b = t + (target - c) / rate
        if t_b > t_event:
            c += (t_event - t) * rate
            t = t_event
            continue
        t, c = t_b, float(target)
        if falls and high_at is not None:
            out.append((high_at, t - high_at))
            high_at = None
            continue
        c = 0.0
        top, cc = pend.pop("top", top), pend.pop("cc", cc)
        if cc > 0 and high_at is None:
            high_at = t
        elif cc == 0 and high_at is not None:
            out.append((high_at, t - high_at))
            high_at = None
    return out


class PWM:
    """A PWM slice output on a pin (``machine.PWM``), RP2040 limits enforced,
    including the frequency shared by the two pins of a slice."""

    def __init__(self, pin: Pin, *, freq: int | None = None, duty_ns: int | None = None,
                 duty_u16: int | None = None) -> None:
        self._pin = pin
        self._freq = 1000
        self._duty_ns = 0
        self._alive = True
        with _lock:
            for other in _live_pwms:
                if _slice_of(other._pin.id) == _slice_of(pin.id):
                    self._freq = other._freq
            _live_pwms.append(self)
        _record("pwm", pin.id, mode="pwm", frequency_hz=float(self._freq), duty_ns=0)
        self._div16, self._top = _div_top(self._freq)
        with _lock:
            _pwm_logs[pin.id] = []
        _log(pin.id, "start", (self._div16, self._top, 0))
        if freq is not None:
            self.freq(freq)
        if duty_ns is not None:
            self.duty_ns(duty_ns)
        if duty_u16 is not None:
            self.duty_u16(duty_u16)

    def freq(self, value: int | None = None) -> int | None:
        if value is None:
            return self._freq
        if not isinstance(value, int):
            # MicroPython's rp2 port takes an integer frequency.
            raise TypeError("can't convert float to int")
        if not _PWM_MIN_FREQUENCY_HZ <= value <= _SYSTEM_CLOCK_HZ / 2:
            raise ValueError("freq out of range")
        with _lock:
            sharing = [p for p in _live_pwms if _slice_of(p._pin.id) == _slice_of(self._pin.id)]
        div16, top = _div_top(value)
        for pwm in sharing:
            pwm._freq = value
            pwm._div16, pwm._top = div16, top
            _log(pwm._pin.id, "div", div16)
            _log(pwm._pin.id, "top", top)
            # MicroPython keeps the duty asked for across a frequency change.
            pwm._write_cc()
            _record("pwm", pwm._pin.id, mode="pwm", frequency_hz=float(value), duty_ns=pwm._duty_ns)
        return None

    def _write_cc(self) -> None:
        cc = int(round(self._duty_ns * _SYSTEM_CLOCK_HZ * 16 / (self._div16 * 1e9)))
        _log(self._pin.id, "cc", min(cc, self._top + 1))

    def duty_ns(self, value: int | None = None) -> int | None:
        if value is None:
            return self._duty_ns
        period_ns = 1_000_000_000 // self._freq
        self._duty_ns = max(0, min(int(value), period_ns))
        self._write_cc()
        _record("pwm", self._pin.id, mode="pwm", frequency_hz=float(self._freq), duty_ns=self._duty_ns)
        return None

    def duty_u16(self, value: int | None = None) -> int | None:
        period_ns = 1_000_000_000 / self._freq
        if value is None:
            return int(round(self._duty_ns / period_ns * 65535))
        return self.duty_ns(int(value / 65535 * period_ns))

    def deinit(self) -> None:
        if self._alive:
            self._alive = False
            with _lock:
                if self in _live_pwms:
                    _live_pwms.remove(self)
            _log(self._pin.id, "stop", None)
            # A stopped slice holds its output low.
            _record("pwm", self._pin.id, mode="gpio", value=0, duty_ns=0)


#: How early a timer's thread wakes to spin to its due time [s].
_TIMER_SPIN_S = 0.005


class Timer:
    """A soft timer (``machine.Timer``) whose callback runs on a host thread."""

    ONE_SHOT = 0
    PERIODIC = 1

    def __init__(self, id: int = -1, **kwargs: Any) -> None:
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.period_ms: float | None = None
        if kwargs:
            self.init(**kwargs)

    def init(
        self,
        *,
        mode: int = PERIODIC,
        period: int | None = None,
        freq: float | None = None,
        callback: Callable[["Timer"], None] | None = None,
    ) -> None:
        self.deinit()
        if freq is not None:
            self.period_ms = 1e3 / freq
        elif period is not None:
            self.period_ms = float(period)
        else:
            raise ValueError("period or freq required")
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=self._run, args=(mode, self.period_ms / 1e3, callback, self._stop), daemon=True
        )
        self._thread.start()

    def _run(self, mode: int, period_s: float, callback: Callable | None, stop: threading.Event) -> None:
        next_t = time.perf_counter() + period_s
        while not stop.wait(max(0.0, next_t - _TIMER_SPIN_S - time.perf_counter())):
            # A board's timer fires on its microsecond; a host thread wakes when
            # the scheduler lets it, so it wakes early and spins the rest.
            while time.perf_counter() < next_t and not stop.is_set():
                time.sleep(0)
            if stop.is_set():
                return
            if callback is not None:
                callback(self)
            if mode == Timer.ONE_SHOT:
                return
            next_t += period_s

    def deinit(self) -> None:
        self._stop.set()
        t = self._thread
        self._thread = None
        if t is not None and t is not threading.current_thread():
            t.join(timeout=1.0)


class ADC:
    """An ADC input (``machine.ADC``): ``read_u16`` returns what a test puts in
    :attr:`sources` for the pin (an int or a function of no arguments), 0 by default."""

    #: pin -> value in [0, 65535] or a callable returning one
    sources: dict[Any, Any] = {}

    def __init__(self, pin: Any) -> None:
        self.id = pin.id if isinstance(pin, Pin) else pin

    def read_u16(self) -> int:
        src = ADC.sources.get(self.id, 0)
        value = src() if callable(src) else src
        return max(0, min(65535, int(value)))


_watchdogs: list["WDT"] = []
#: set when a watchdog expired and "reset the chip"
resets: list[float] = []


class WDT:
    """The hardware watchdog (``machine.WDT``).  When it is not fed for
    ``timeout`` ms it resets the "chip": every PWM slice stops and every pin goes
    back to an input with its gate pulled low (recorded as a ``reset`` event)."""

    def __init__(self, id: int = 0, timeout: int = 5000) -> None:
        self.timeout_ms = timeout
        self.last_feed_s = time.perf_counter()
        self._stop = threading.Event()
        with _lock:
            _watchdogs.append(self)
        threading.Thread(target=self._watch, daemon=True).start()

    def feed(self) -> None:
        self.last_feed_s = time.perf_counter()

    def _watch(self) -> None:
        while not self._stop.wait(0.002):
            if time.perf_counter() - self.last_feed_s > self.timeout_ms / 1e3:
                with _lock:
                    pwms = list(_live_pwms)
                    pins = list(_pins)
                for pwm in pwms:
                    pwm.deinit()
                for pin_id in pins:
                    _record("reset", pin_id, mode="gpio", value=0)
                resets.append(time.perf_counter())
                return


#: what disable_irq holds on the host: the timers' threads and the main loop
#: share the firmware's heat estimate, as IRQs and the main loop do on a board
_irq = threading.RLock()
WDT_RESET = 3


def disable_irq() -> bool:
    _irq.acquire()
    return True


def enable_irq(state: bool = True) -> None:
    _irq.release()
