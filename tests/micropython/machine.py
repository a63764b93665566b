# The stand-in machine module for the firmware under the WebAssembly MicroPython:
# the chip model (rp2040.py, tactilize/boardhost/rp2040.py copied next to it) on
# MicroPython's own clock, with every call a real RP2040 would see recorded in
# `log`.  MicroPython code (it runs inside MicroPython, not on the host).

import time

import rp2040
import rp2040_machine

log = []
inputs = {}
adc_values = {}
feeds = [0]
_clock = [0, time.ticks_us()]


def _now_us():
    # MicroPython's wrapping ticks, unwrapped (read often enough: well under 2**29 us apart)
    t = time.ticks_us()
    _clock[0] += time.ticks_diff(t, _clock[1])
    _clock[1] = t
    return _clock[0]


chip = rp2040.Chip(_now_us)
chip.gpio_inputs = inputs
chip.adc_inputs = adc_values
_m = rp2040_machine.Machine(chip)
mem32 = _m.mem32
WDT_RESET = rp2040.WDT_RESET
PWRON_RESET = rp2040.PWRON_RESET


def disable_irq():
    return 1


def enable_irq(state=1):
    pass


def reset_cause():
    return _m.reset_cause()


def freq(hz=None):
    return _m.freq(hz)


class Pin(_m.Pin):
    def __init__(self, id, mode=-1, pull=-1, value=None):
        log.append(["Pin", id, mode, value])
        super().__init__(id, mode, pull, value)

    def value(self, v=None):
        if v is None:
            return super().value()
        log.append(["value", self.id, v])
        super().value(v)


class PWM(_m.PWM):
    def __init__(self, pin, freq=None, duty_u16=None, duty_ns=None):
        log.append(["PWM", pin.id])
        super().__init__(pin, freq=freq, duty_u16=duty_u16, duty_ns=duty_ns)

    def freq(self, f=None):
        if f is None:
            return super().freq()
        log.append(["freq", self.gpio, f])
        super().freq(f)

    def duty_ns(self, ns=None):
        if ns is None:
            return super().duty_ns()
        log.append(["duty_ns", self.gpio, ns])
        super().duty_ns(ns)

    def duty_u16(self, v=None):
        if v is None:
            return super().duty_u16()
        log.append(["duty_u16", self.gpio, v])
        super().duty_u16(v)

    def deinit(self):
        log.append(["deinit", self.gpio])
        super().deinit()


class ADC(_m.ADC):
    def __init__(self, pin):
        log.append(["ADC", pin])
        super().__init__(pin)


class Timer(_m.Timer):
    # No scheduler: an armed timer never fires by itself; the tests call its callback.
    def __init__(self, id=-1, mode=1, period=None, freq=None, callback=None, tick_hz=1000):
        log.append(["Timer", mode, period, freq])
        super().__init__(id, mode=mode, callback=callback, period=period, freq=freq, tick_hz=tick_hz)

    def deinit(self):
        log.append(["Timer.deinit"])
        super().deinit()


class WDT(_m.WDT):
    def __init__(self, id=0, timeout=5000):
        log.append(["WDT", timeout])
        super().__init__(id, timeout)

    def feed(self):
        feeds[0] += 1
        super().feed()
