# A stand-in for MicroPython's machine module, for the firmware run under the
# WebAssembly MicroPython: it records every call a real RP2040 would see.
# MicroPython code (it runs inside MicroPython, not on the host).

log = []
inputs = {}
adc_values = {}
feeds = [0]


WDT_RESET = 3


def disable_irq():
    return 1


def enable_irq(state=1):
    pass


def reset_cause():
    return 1


class Pin:
    IN = 0
    OUT = 1
    PULL_UP = 1
    PULL_DOWN = 2

    def __init__(self, id, mode=-1, pull=-1, value=None):
        self.id = id
        self.mode = mode
        log.append(["Pin", id, mode, value])

    def value(self, v=None):
        if v is None:
            return inputs.get(self.id, 1)
        log.append(["value", self.id, v])


class PWM:
    def __init__(self, pin, freq=None, duty_u16=None):
        self.pin = pin.id
        self.f = 1000
        log.append(["PWM", self.pin])
        if freq is not None:
            self.freq(freq)
        if duty_u16 is not None:
            self.duty_u16(duty_u16)

    def freq(self, f=None):
        if f is None:
            return self.f
        self.f = f
        log.append(["freq", self.pin, f])

    def duty_ns(self, ns):
        log.append(["duty_ns", self.pin, ns])

    def duty_u16(self, v):
        log.append(["duty_u16", self.pin, v])

    def deinit(self):
        log.append(["deinit", self.pin])


class ADC:
    def __init__(self, pin):
        self.id = pin
        log.append(["ADC", pin])

    def read_u16(self):
        return adc_values.get(self.id, 0)


class Timer:
    ONE_SHOT = 0
    PERIODIC = 1

    def __init__(self, id=-1, mode=1, period=None, freq=None, callback=None):
        self.callback = callback
        log.append(["Timer", mode, period, freq])

    def deinit(self):
        log.append(["Timer.deinit"])


class WDT:
    def __init__(self, id=0, timeout=5000):
        log.append(["WDT", timeout])

    def feed(self):
        feeds[0] += 1
