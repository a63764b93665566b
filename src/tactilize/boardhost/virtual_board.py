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
from . import rp2040, rp2040_machine

__all__ = ["VirtualMachine", "VirtualBoard", "firmware", "install", "peak_on_wire"]


def firmware() -> ModuleType:
    """The controller firmware module, loaded against the host's ``machine`` (once per process)."""
    from .emulator import load_firmware

    return load_firmware()


class WatchdogReset(Exception):
    """Raised inside the firmware's busy wait when the watchdog resets the chip."""


class _Edges:
    """gpio -> the pad's level changes [(t [us], level)], read from the chip's history."""

    def __init__(self, chip: rp2040.Chip) -> None:
        self._chip = chip

    def get(self, gpio: Any, default: Any = None) -> list[tuple[float, int]]:
        if gpio not in self._chip.history:
            return [] if default is None else default
        return self[gpio]

    def __getitem__(self, gpio: Any) -> list[tuple[float, int]]:
        end_h = self._chip.t_h() + 1
        return [(t / rp2040.H_PER_US, int(lev)) for t, lev in self._chip.edges_h(gpio, end_h)]


class VirtualMachine(rp2040_machine.Machine):
    """MicroPython's ``machine`` on the chip model (:mod:`~tactilize.boardhost.rp2040`),
    on a simulated clock [us]: timers fire at their due instants, ``sleep_us`` moves
    the clock, and the watchdog resets the board when it is not fed in time.

    Parameters
    ----------
    start_us : int
        The chip's microsecond timer when the board's clock reads 0 (its ticks
        start there: just below 2**30 to run across the wrap).
    """

    def __init__(self, start_us: int = 0) -> None:
        self.now_us = 0
        super().__init__(rp2040.Chip(lambda: self.now_us, timer_us=start_us))
        self._timers: list[tuple[int, int, Any]] = []
        self._order = itertools.count()
        self.chip.scheduler = self
        #: called when the watchdog expires (the board resets the chip and boots again)
        self.on_watchdog: Callable[[], None] | None = None

    # -- the clock the firmware reads
    def sleep_us(self, us: int) -> None:
        """A busy wait; the watchdog expiring inside it resets the chip there and
        then (the firmware's code stops at that instant)."""
        end = self.now_us + max(0, int(us))
        due = self.chip.wdt_due_us
        if due is not None and self.on_watchdog is not None and due <= end:
            self.now_us = max(self.now_us, int(due))
            raise WatchdogReset()
        self.now_us = end

    def _run(self, fn: Callable[..., Any], *args: Any) -> None:
        # Firmware code, cut short by a watchdog reset in a busy wait.
        try:
            fn(*args)
        except WatchdogReset:
            if self.on_watchdog is not None:
                self.on_watchdog()

    @property
    def edges(self) -> _Edges:
        """gpio -> level changes [(t [us], level)] of the pad (all of them: GPIO and PWM)."""
        return _Edges(self.chip)

    @property
    def adc(self) -> dict[Any, Any]:
        """gpio (26..29) -> the true ADC reading (read_u16 at the right reference)."""
        return self.chip.adc_inputs

    # -- the scheduler the chip's timers use
    def arm(self, timer: Any, due_us: int) -> None:
        timer._due_us = int(due_us)
        heapq.heappush(self._timers, (int(due_us), next(self._order), timer))

    def cancel(self, timer: Any) -> None:
        timer._due_us = None  # its heap entry is dropped when it comes up

    def run_until(self, t_us: int, tick: Callable[[], None], poll_us: int) -> None:
        """Fire every timer due before ``t_us``, the watchdog if it expires, and call
        ``tick`` every ``poll_us`` (the main loop's pass)."""
        next_tick = (self.now_us // poll_us + 1) * poll_us
        chip = self.chip
        while True:
            if chip.wdt_expired() and self.on_watchdog is not None:
                self.on_watchdog()
                continue
            due = self._timers[0][0] if self._timers else None
            wdt = chip.wdt_due_us
            if wdt is not None and wdt <= min(next_tick, t_us) and (due is None or wdt < due):
                self.now_us = max(self.now_us, int(wdt))
                if chip.wdt_expired() and self.on_watchdog is not None:
                    self.on_watchdog()
                continue
            if due is not None and due <= min(next_tick, t_us):
                _, _, timer = heapq.heappop(self._timers)
                if not timer.alive or getattr(timer, "_due_us", None) != due:
                    continue
                self.now_us = max(self.now_us, due)
                if timer.mode == timer.PERIODIC:
                    self.arm(timer, due + timer.period_us)
                else:
                    timer.alive = False
                    chip.cancel(timer)
                if timer.callback is not None:
                    self._run(timer.callback, timer)
                continue
            if next_tick <= t_us:
                self.now_us = max(self.now_us, next_tick)
                self._run(tick)
                next_tick += poll_us
                continue
            self.now_us = max(self.now_us, t_us)
            return

    def finish(self) -> None:
        """Nothing to bring up to date: the chip's history is exact at every write."""

    def channel_levels(self, pin: Any, bias_pin: Any, end_us: float) -> tuple[list[float], list[float]]:
        """(durations [s], switch levels) of one channel's gate up to ``end_us``: the
        gate is the pulse pin OR-ed with the bias pin; the 20 kHz bias counts as its
        mean level, slower trains and GPIO pulses as exact pulses."""
        chip = self.chip
        a = chip.levels_us(pin, end_us)
        b = chip.levels_us(bias_pin, end_us) if bias_pin is not None else []
        points = sorted({0.0, float(end_us)} | {t for t, _ in a} | {t for t, _ in b})
        durs: list[float] = []
        levels: list[float] = []
        ia = ib = 0
        la = lb = 0.0
        for t0, t1 in zip(points, points[1:]):
            while ia < len(a) and a[ia][0] <= t0:
                la = a[ia][1]
                ia += 1
            while ib < len(b) and b[ib][0] <= t0:
                lb = b[ib][1]
                ib += 1
            durs.append((t1 - t0) * 1e-6)
            levels.append(max(la, lb))
        return durs, levels


def peak_on_wire(durations_s: Any, levels: Any, circuit: str | Circuit = "aa-resistor",
                 spec: WireSpec | None = None, start_c: float | None = None, air_c: float | None = None) -> float:
    """The wire model's highest temperature [deg C] under a switch schedule, in air
    at ``air_c`` [deg C] (default: the envelope's hottest design air), starting from
    that air or from ``start_c`` [deg C]."""
    spec = WireSpec.resolve(spec)
    env = build_envelope(spec, circuit)
    air = env.design_ambient_c if air_c is None else float(air_c)
    model = WireModel(spec.replace(ambient_c=air), Circuit.resolve(circuit, spec),
                      temperature_c=air if start_c is None else start_c)
    edges: list = []
    model.run(durations_s, levels, edges=edges)
    return max([model.initial_temperature_c] + [T for T, _ in edges])


SetAttr = Callable[[Any, str, Any], None]


def install(fw: ModuleType, set_attr: SetAttr, start_us: int = 0) -> VirtualMachine:
    """Run the loaded firmware module ``fw`` on a fresh virtual board; every patch
    goes through ``set_attr(obj, name, value)`` (a test's ``monkeypatch.setattr``,
    or :class:`VirtualBoard`'s, which undoes them on close).  The firmware reads the
    chip's wrapping ticks (``start_us``: the chip's timer at clock 0)."""
    vm = VirtualMachine(start_us)
    set_attr(fw, "machine", vm)
    for name, fn in (("_ticks_us", vm.ticks_us), ("_ticks_ms", vm.ticks_ms), ("_ticks_diff", vm.ticks_diff),
                     ("_ticks_add", vm.ticks_add), ("_sleep_us", vm.sleep_us)):
        for module in (fw, fw.F):
            if hasattr(module, name):
                set_attr(module, name, fn)
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

    The board boots as ``main.py`` does (a ``Controller``, then the hardware
    watchdog that the main loop feeds at every pass) and :meth:`reset` boots it
    again after a power-on, watchdog or soft reset, with the chip's state carried
    over as that reset carries it (:mod:`~tactilize.boardhost.rp2040`); the pins'
    history, hence :meth:`peak_c`, runs on across resets.

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
        The board has just started (as after a watchdog reset): its heat
        estimates start at the budget, as every board's do after any start.
        By default the first boot is of a board idle long enough for them to
        have cooled, as the wire the judge starts from
        (``Controller(assume_cold=True)``); every :meth:`reset` boots hot.
    start_us : int
        The chip's microsecond timer at the board's clock 0 [us] (e.g. just below
        2**30: the ticks wrap soon after the start).
    air_c : float, optional
        The room's air [deg C] the wire is judged in; the envelope's hottest design
        air by default.
    chip_temp_c : float
        The chip's temperature [deg C] (what ADC input 4 reads).
    design_air_c : float, optional
        The hottest air [deg C] the board's stored config is made for (default
        the envelope's design ambient).
    watchdog : bool
        Start the hardware watchdog at boot, as ``main.py`` does.
    """

    def __init__(self, store: str | Path | None = None, circuit: str | Circuit = "aa-resistor", *,
                 set_attr: SetAttr | None = None, after_watchdog_reset: bool = False, start_us: int = 0,
                 air_c: float | None = None, chip_temp_c: float = 27.0, watchdog: bool = True,
                 design_air_c: float | None = None) -> None:
        from .board import board_config_text

        self.fw = fw = firmware()
        self._patches = _Patches()
        self._tmp = tempfile.TemporaryDirectory(prefix="tactilize-board-") if store is None else None
        self.root = Path(self._tmp.name if self._tmp is not None else str(store))
        self.vm = install(fw, set_attr or self._patches.set, start_us)
        self.chip = self.vm.chip
        self.chip.chip_temp_c = chip_temp_c
        if after_watchdog_reset:
            self.chip.reason = 1  # the watchdog's REASON register, as after its reset
        (self.root / fw.W.CONFIG_FILE).write_text(board_config_text(None, circuit, design_air_c))
        self.sent: list[bytes] = []
        self.circuit = circuit
        self.air_c = air_c
        self.seq = 0
        self._watchdog = watchdog
        self.vm.on_watchdog = lambda: self.reset("watchdog")
        self._boot(assume_cold=not after_watchdog_reset)

    def _boot(self, assume_cold: bool = False) -> None:
        # main.py: the controller, then machine.WDT, which run() feeds (and a retune's wait too).
        self.fw.C.WDT[0] = None
        self.ctl = self.fw.Controller(self.sent.append, store=str(self.root) + "/", assume_cold=assume_cold)
        self.wdt = self.vm.WDT(timeout=self.fw.WDT_TIMEOUT_MS) if self._watchdog else None
        self.fw.C.WDT[0] = self.wdt

    def _pass(self) -> None:
        # One pass of the firmware's main loop (controller.run): feed, then tick.
        if self.wdt is not None:
            self.wdt.feed()
        self.ctl.tick()

    def reset(self, kind: str) -> None:
        """Reset the board now and boot it again.

        Parameters
        ----------
        kind : {"power", "watchdog", "soft"}
            ``"power"``: everything cleared, the pins float (the gates' pull-downs
            hold them low); ``"watchdog"``: the chip resets but its watchdog scratch
            registers survive and ``reset_cause()`` says ``WDT_RESET``; ``"soft"``:
            MicroPython restarts (PWM slices stopped where they stood, soft timers
            gone; pins, GPIO levels, the running watchdog and the ticks carry on).
        """
        self.chip.reset(kind)
        self._boot()

    @property
    def resets(self) -> list[tuple[float, str]]:
        """Every reset so far: (board clock [us], kind)."""
        return list(self.chip.reset_log)

    def adc_reference_error(self, k: float) -> None:
        """Every ADC reading ``k`` times the truth (a wrong ADC reference), from now on."""
        self.chip.adc_gain = float(k)

    @property
    def chip_temp_c(self) -> float:
        """The chip's temperature [deg C] (ADC input 4 reads it)."""
        return float(self.chip.chip_temp_c)

    @chip_temp_c.setter
    def chip_temp_c(self, value: float) -> None:
        self.chip.chip_temp_c = float(value)

    def close(self) -> None:
        """Put the firmware module back as it was; remove the temporary store."""
        self.fw.C.WDT[0] = None
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
        self.receive(P.encode_frame(self.seq, command, payload))

    def receive(self, data: bytes) -> None:
        """Bytes as a host's port writes them (whole frames or not), received at once, at the
        board's clock now (:class:`~tactilize.boardhost.virtual_serial.VirtualSerialOutput` writes here)."""
        self.vm._run(self.ctl.feed, bytes(data))

    def set(self, channel: int, f_hz: float, w_s: float, amp: float = 1.0, regularity: float | None = None) -> None:
        self.send(P.Command.SET, P.encode_set_channel(channel, f_hz, w_s, amp, regularity))

    def until(self, t_s: float) -> None:
        """Run the board until its clock reads ``t_s`` [s].

        Every main-loop pass is run (one per ``POLL_MS``): an idle hour of board
        time costs the firmware's tick 720 000 times, a few seconds of host time.
        """
        self.vm.run_until(int(round(t_s * 1e6)), self._pass, self.fw.POLL_MS * 1000)

    def replies(self) -> list:
        """The frames the board wrote since the last call."""
        frames = P.FrameDecoder().feed(b"".join(self.sent))
        self.sent.clear()
        return frames

    def peak_c(self, channel: int = 0, air_c: float | None = None, start_c: float | None = None) -> float:
        """The wire model's peak [deg C] under what the channel's pins did so far.

        Parameters
        ----------
        channel : int
            The channel whose gate (pulse pin OR bias pin) is judged.
        air_c : float, optional
            The air [deg C]; the board's ``air_c``, else the envelope's hottest design air.
        start_c : float, optional
            The wire's temperature at the board's clock 0 [deg C]; the air's by default.
        """
        pins = (self.fw.CHANNEL_PINS[channel], self.fw.BIAS_PINS[channel])
        durs, levels = self.vm.channel_levels(*pins, self.vm.now_us)
        air = self.air_c if air_c is None else air_c
        return peak_on_wire(durs, levels, self.circuit, start_c=start_c, air_c=air)

    def pulse_starts_us(self, channel: int = 0) -> list[float]:
        """When each pulse on the channel's gate pin began [us, board clock], in order
        (GPIO pulses and a PWM slice's alike: the pad's rising edges)."""
        pin = self.fw.CHANNEL_PINS[channel]
        return [t for t, level in self.vm.edges.get(pin, []) if level]

    def pulse_count(self, channel: int = 0) -> int:
        return len(self.pulse_starts_us(channel))
