# MicroPython's `machine` module (what the controller firmware uses of it) on
# the chip model of rp2040.py: Pin, PWM, Timer, WDT, ADC, mem32 and the module
# functions, computed as MicroPython's rp2 port computes them (the sources:
# docs/references.md, section 10 (the chip model)).  The chip is the hardware;
# this is the port's API over it.
#
# MicroPython-compatible code only: the same file runs on the host and inside
# the WebAssembly MicroPython, next to rp2040.py.

try:
    from rp2040 import (  # type: ignore[import-not-found]  # inside MicroPython: the file next to this one
        ADC_FIRST_GPIO, ADC_TEMP_CHANNEL, PWRON_RESET, SYS_CLK_HZ, WDT_RESET, WDT_TIMEOUT_MAX_MS,
        pwm_div_top, slice_hz, ticks_add, ticks_diff, timer_delta_us,
    )
except ImportError:  # on the host, inside the package
    from tactilize.boardhost.rp2040 import (
        ADC_FIRST_GPIO, ADC_TEMP_CHANNEL, PWRON_RESET, SYS_CLK_HZ, WDT_RESET, WDT_TIMEOUT_MAX_MS,
        pwm_div_top, slice_hz, ticks_add, ticks_diff, timer_delta_us,
    )


class Machine:
    """MicroPython's `machine` module (what the firmware uses of it) on a chip:
    its classes are bound to that chip."""

    PWRON_RESET = PWRON_RESET
    WDT_RESET = WDT_RESET

    def __init__(self, chip):
        self.chip = chip
        ch = chip
        self.mem32 = _Mem32(chip)

        class Pin:
            IN = 0
            OUT = 1
            OPEN_DRAIN = 2
            ALT = 3
            PULL_UP = 1
            PULL_DOWN = 2

            def __init__(self, id, mode=-1, pull=-1, value=None, alt=None):
                self.id = id
                self._pull = pull
                self.init(mode, pull, value=value)

            def init(self, mode=-1, pull=-1, value=None, alt=None):
                if pull != -1:
                    self._pull = pull
                if mode == Pin.OUT:
                    # the level first, then the pad back to SIO, driving
                    ch.sio(self.id, func="sio", out=value, oe=True)
                elif mode == Pin.IN:
                    ch.sio(self.id, func="sio", oe=False)

            def value(self, v=None):
                if v is None:
                    p = ch.pad(self.id)
                    if p[2]:
                        return p[1]
                    default = 1 if self._pull == Pin.PULL_UP else 0
                    return ch.gpio_inputs.get(self.id, default)
                ch.sio(self.id, out=v)
                return None

            def on(self):
                self.value(1)

            def off(self):
                self.value(0)

            def __call__(self, v=None):
                return self.value(v)

        class PWM:
            def __init__(self, pin, freq=None, duty_u16=None, duty_ns=None):
                # MicroPython forgets the channel's duty and connects the pad to
                # the slice as it stands: counter, registers and enable untouched.
                gpio = pin.id if hasattr(pin, "id") else pin
                self.gpio = gpio
                self.slice = (gpio >> 1) & 7
                self.channel = gpio & 1
                ch.pwm_duty.pop(self._key(), None)
                if freq is not None:
                    self.freq(freq)
                if duty_u16 is not None:
                    self.duty_u16(duty_u16)
                if duty_ns is not None:
                    self.duty_ns(duty_ns)
                ch.sio(gpio, func="pwm")
                self._notify()

            def _key(self):
                return self.slice * 2 + self.channel

            def _start(self):
                if ch.freq_set[self.slice] and self._key() in ch.pwm_duty:
                    ch.pwm_write(self.slice, en=True)

            def _notify(self, gpios=None):
                # what MicroPython was asked, for the pads on this slice's outputs
                hz = self.freq()
                for g in (gpios if gpios is not None else [self.gpio]):
                    d = ch.pwm_duty.get(((g >> 1) & 7) * 2 + (g & 1))
                    duty_ns = 0
                    if d is not None:
                        duty_ns = d[1] if d[0] == "ns" else int(d[1] / 65535 * 1e9 / max(1, hz))
                    ch._notify("pwm", g, {"mode": "pwm", "frequency_hz": float(hz), "duty_ns": duty_ns})

            def freq(self, value=None):
                s = ch.slices[self.slice]
                if value is None:
                    return s.freq_hz() if ch.freq_set[self.slice] else 0
                if not isinstance(value, int):
                    raise TypeError("can't convert float to int")
                div16, top = pwm_div_top(value)
                ch.pwm_write(self.slice, div16=div16, top=top)
                ch.freq_set[self.slice] = True
                for key in (self.slice * 2, self.slice * 2 + 1):
                    d = ch.pwm_duty.get(key)
                    if d is not None:
                        self._set_cc(key & 1, d)
                self._start()
                self._notify([g for g in range(30) if (g >> 1) & 7 == self.slice
                              and ch.pads.get(g, ("null",))[0] == "pwm"] or [self.gpio])
                return None

            def _set_cc(self, channel, d):
                s = ch.slices[self.slice]
                if d[0] == "u16":
                    cc = (min(d[1], 65535) * (s.ptop + 1) + 65535 // 2) // 65535
                else:
                    hz = slice_hz(s.div16 // 2, s.div16)
                    cc = min((d[1] * hz + 500000000) // 1000000000, s.ptop + 1)
                ch.pwm_write(self.slice, cc=(channel, cc))

            def duty_u16(self, value=None):
                s = ch.slices[self.slice]
                if value is None:
                    if self._key() not in ch.pwm_duty or not ch.freq_set[self.slice]:
                        return 0
                    cc = s.pcc[self.channel]
                    return (cc * 65535 + (s.ptop + 1) // 2) // (s.ptop + 1)
                d = ("u16", int(value))
                self._set_cc(self.channel, d)
                ch.pwm_duty[self._key()] = d
                self._start()
                self._notify()
                return None

            def duty_ns(self, value=None):
                s = ch.slices[self.slice]
                if value is None:
                    if self._key() not in ch.pwm_duty or not ch.freq_set[self.slice]:
                        return 0
                    hz = slice_hz(s.div16 // 2, s.div16)
                    return (s.pcc[self.channel] * 1000000000 + hz // 2) // hz
                d = ("ns", int(value))
                self._set_cc(self.channel, d)
                ch.pwm_duty[self._key()] = d
                self._start()
                self._notify()
                return None

            def deinit(self):
                # Stops the slice (both of its outputs); the pad stays on it.
                ch.pwm_write(self.slice, en=False)
                ch._notify("pwm", self.gpio, {"mode": "pwm", "stopped": True})

        class ADC:
            CORE_TEMP = ADC_TEMP_CHANNEL

            def __init__(self, source):
                if hasattr(source, "id"):
                    source = source.id
                if isinstance(source, int) and 0 <= source <= ADC_TEMP_CHANNEL:
                    self.channel = source
                elif isinstance(source, int) and ADC_FIRST_GPIO <= source < ADC_FIRST_GPIO + 4:
                    self.channel = source - ADC_FIRST_GPIO
                else:
                    raise ValueError("Pin doesn't have ADC capabilities")
                self.id = source

            def read_u16(self):
                return ch.adc_read_u16(self.channel)

        class Timer:
            ONE_SHOT = 0
            PERIODIC = 1

            def __init__(self, id=-1, mode=1, callback=None, period=None, tick_hz=1000, freq=None, hard=False):
                if id != -1:
                    raise ValueError("Timer doesn't exist")
                self.alive = False
                self.callback = None
                self.mode = mode
                self.period_us = 0
                if period is not None or freq is not None or callback is not None:
                    self.init(mode=mode, callback=callback, period=period, tick_hz=tick_hz, freq=freq, hard=hard)

            def init(self, mode=1, callback=None, period=None, tick_hz=1000, freq=None, hard=False):
                self.alive = False
                ch.cancel(self)
                self.mode = mode
                self.callback = callback
                self.period_us = timer_delta_us(period, freq, tick_hz)
                self.alive = True
                ch.arm(self, ch.now_us() + self.period_us)

            def deinit(self):
                self.alive = False
                ch.cancel(self)

        class WDT:
            def __init__(self, id=0, timeout=5000):
                if id != 0:
                    raise ValueError("WDT(%d) doesn't exist" % id)
                if timeout > WDT_TIMEOUT_MAX_MS:
                    raise ValueError("timeout exceeds %d" % WDT_TIMEOUT_MAX_MS)
                self.timeout_ms = timeout
                ch.wdt_start(timeout)

            def feed(self):
                ch.wdt_feed()

        self.Pin = Pin
        self.PWM = PWM
        self.ADC = ADC
        self.Timer = Timer
        self.WDT = WDT

    def freq(self, hz=None):
        return SYS_CLK_HZ

    def reset_cause(self):
        return WDT_RESET if self.chip.reason else PWRON_RESET

    def disable_irq(self):
        return 1

    def enable_irq(self, state=1):
        return None

    # MicroPython's time functions on this chip's clock
    def ticks_us(self):
        return self.chip.ticks_us()

    def ticks_ms(self):
        return self.chip.ticks_ms()

    ticks_diff = staticmethod(ticks_diff)
    ticks_add = staticmethod(ticks_add)


class _Mem32:
    def __init__(self, chip):
        self.chip = chip

    def __getitem__(self, addr):
        return self.chip.mem32_read(addr)

    def __setitem__(self, addr, value):
        self.chip.mem32_write(addr, value)
