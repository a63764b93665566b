# One model of the RP2040 and of MicroPython's rp2 port, as the controller
# firmware sees them: ticks, GPIO pads, PWM slices, soft timers, the watchdog
# (and its scratch registers), the ADC with its temperature sensor, and the
# three kinds of reset.  MicroPython's `machine` API over this chip is
# rp2040_machine.py.  The facts and their sources: docs/references.md,
# section 10 (the chip model).
#
# MicroPython-compatible code only (no dataclasses, enum, typing, f-strings,
# annotations): the same file runs on the host (tactilize.boardhost's virtual
# board and real-time emulator) and inside the WebAssembly MicroPython (the
# tests' stand-in machine module imports it from the file system).
#
# Time: the chip takes its clock from the caller, `now_us()` in microseconds
# since any origin, never going back.  Inside, instants are integers in units of
# 1/16 of a system-clock cycle ("h", 0.5 ns at 125 MHz), the grain of the PWM's
# 8.4 fractional divider, so a slice's edges are exact.  A pad's history is a
# list of segments [start_h, origin_h, period_h, high_h]: from start_h on, the
# pad is high when (t - origin_h) mod period_h < high_h; period_h == 0 is a
# constant level high_h (0 or 1).

import struct

SYS_CLK_HZ = 125000000
# h per microsecond: 16 per cycle, 125 cycles per us.
H_PER_US = 16 * SYS_CLK_HZ // 1000000

# -------------------------------------------------------------------- ticks
# rp2: a small int holds 31 bits, so the ticks period is 2**30.
TICKS_PERIOD = 1 << 30
TICKS_MAX = TICKS_PERIOD - 1
TICKS_HALF = TICKS_PERIOD // 2


def ticks_diff(end, start):
    """Signed difference end - start of two tick values, in [-2**29, 2**29)."""
    return ((end - start + TICKS_HALF) & TICKS_MAX) - TICKS_HALF


def ticks_add(ticks, delta):
    """ticks + delta on the wrapping clock; a |delta| of 2**29 or more cannot be
    told apart by ticks_diff, so it raises OverflowError as MicroPython does."""
    if delta <= -TICKS_HALF or delta >= TICKS_HALF:
        raise OverflowError("ticks interval overflow")
    return (ticks + delta) & TICKS_MAX


# -------------------------------------------------------------------- constants
PWRON_RESET = 1
WDT_RESET = 3
WDT_TIMEOUT_MAX_MS = 8388
WATCHDOG_BASE = 0x40058000
WATCHDOG_REASON = WATCHDOG_BASE + 0x08
WATCHDOG_SCRATCH0 = WATCHDOG_BASE + 0x0C
# The ADC's full scale [V] on a Pico (its 3.3 V reference) and the temperature
# sensor's line: V = 0.706 V at 27 C, -1.721 mV/K.
ADC_VREF_V = 3.3
TEMP_V27 = 0.706
TEMP_SLOPE_V_K = 0.001721
ADC_TEMP_CHANNEL = 4
ADC_FIRST_GPIO = 26
# MicroPython's freq(): TOP at most 65534, so duty_u16 65535 can reach 100 %.
PWM_TOP_MAX = 65534


def f32(x):
    """x rounded to single precision (the rp2 port's float)."""
    return struct.unpack("f", struct.pack("f", x))[0]


def timer_delta_us(period=None, freq=None, tick_hz=1000):
    """The alarm interval [us] machine.Timer arms: freq in single precision,
    1e6 / freq truncated; or period * 1e6 // tick_hz; at least 1."""
    if freq is not None:
        delta = int(f32(1000000.0 / f32(float(freq))))
    elif period is not None:
        delta = int(period) * 1000000 // int(tick_hz)
    else:
        delta = 0xFFFFFFFF * 1000000 // int(tick_hz)
    return max(1, delta)


def slice_hz(offset, div16):
    # floor((16 F + offset) / div16)
    return (16 * SYS_CLK_HZ + offset) // div16


def pwm_div_top(freq):
    """(div16, top) machine.PWM.freq(freq) writes: DIV 1 when TOP fits, else the
    smallest divider for the most resolution, TOP rounded."""
    if freq <= 0:
        raise ValueError("freq too small")
    if (SYS_CLK_HZ + freq // 2) // freq < PWM_TOP_MAX:
        div16 = 16
        top = (SYS_CLK_HZ + freq // 2) // freq - 1
    else:
        div16 = slice_hz(PWM_TOP_MAX * freq - 1, PWM_TOP_MAX * freq)
        top = slice_hz(div16 * freq // 2, div16 * freq) - 1
    if div16 < 16:
        raise ValueError("freq too large")
    if div16 >= 256 * 16:
        raise ValueError("freq too small")
    return div16, top


def temp_sensor_u16(temp_c, gain=1.0):
    """read_u16 of ADC input 4 at a chip temperature [C]."""
    v = TEMP_V27 - (temp_c - 27.0) * TEMP_SLOPE_V_K
    return _u16_of_raw(_raw12(v / ADC_VREF_V * 65535.0 * gain))


def temp_of_u16(u16):
    """The chip temperature [C] the datasheet's formula gives for a read_u16."""
    v = u16 * ADC_VREF_V / 65535.0
    return 27.0 - (v - TEMP_V27) / TEMP_SLOPE_V_K


def _raw12(u16_value):
    # The converter's 12-bit result for an input worth u16_value on a 16-bit scale.
    raw = int(u16_value) >> 4
    return 0 if raw < 0 else (4095 if raw > 4095 else raw)


def _u16_of_raw(raw):
    # MicroPython stretches the 12-bit result to 16 bits: raw << 4 | raw >> 8.
    return (raw << 4) | (raw >> 8)


def _norm(seg):
    # A periodic segment that is always low or always high is a level.
    t, origin, period, high = seg
    if period > 0 and high <= 0:
        return [t, 0, 0, 0]
    if period > 0 and high >= period:
        return [t, 0, 0, 1]
    return seg


def _same_wave(a, b):
    if a[2] != b[2] or a[3] != b[3]:
        return False
    return a[2] == 0 or (a[1] - b[1]) % a[2] == 0


def level_at(seg, t_h):
    t, origin, period, high = seg
    if period == 0:
        return high
    return 1 if (t_h - origin) % period < high else 0


# -------------------------------------------------------------------- PWM slice
class Slice:
    """One PWM slice: a 16-bit counter at sys_clk / DIV from 0 to TOP, then 0;
    output A (B) high while the counter is below CC_A (CC_B).  TOP and CC are
    double-buffered: software's copies reach the counter at a wrap while the slice
    runs, at once while it is stopped; DIV applies at once; a stopped counter
    keeps its value and resumes from it."""

    def __init__(self, index):
        self.index = index
        self.power_on(0)

    def power_on(self, t_h):
        # The registers' reset values: DIV 1.0, TOP 0xffff, CC 0, CTR 0, off.
        self.en = False
        self.div16 = 16
        self.top = self.ptop = 0xFFFF
        self.cc = [0, 0]
        self.pcc = [0, 0]
        self.ctr = 0
        self.sub_h = 0  # h into the count in progress
        self.t_h = t_h

    def advance(self, t_h):
        """Bring the counter to instant t_h (latching the buffers at the first wrap)."""
        if t_h <= self.t_h:
            return
        if self.en:
            total = self.sub_h + (t_h - self.t_h)
            n = total // self.div16
            self.sub_h = total % self.div16
            c = self.ctr + n
            if c > self.top:
                c -= self.top + 1
                self.top = self.ptop
                self.cc = [self.pcc[0], self.pcc[1]]
                c %= self.top + 1
            self.ctr = c
        self.t_h = t_h

    def origin_h(self):
        # When the counter was 0 in this period, at the present divider.
        return self.t_h - self.ctr * self.div16 - self.sub_h

    def segments(self, ch):
        """The output of channel ch (0: A, 1: B) from now on, as segments."""
        t = self.t_h
        if not self.en:
            return [[t, 0, 0, 1 if self.ctr < self.cc[ch] else 0]]
        period = (self.top + 1) * self.div16
        origin = self.origin_h()
        out = [_norm([t, origin, period, min(self.cc[ch], self.top + 1) * self.div16])]
        if self.ptop != self.top or self.pcc[ch] != self.cc[ch]:
            wrap = origin + period
            out.append(_norm([wrap, wrap, (self.ptop + 1) * self.div16,
                              min(self.pcc[ch], self.ptop + 1) * self.div16]))
        return out

    def write_div(self, div16):
        # The count in progress goes on at the new rate for what is left of it.
        self.sub_h = self.sub_h * div16 // self.div16
        self.div16 = div16

    def write_top(self, top):
        self.ptop = top
        if not self.en:
            self.top = top

    def write_cc(self, ch, cc):
        self.pcc[ch] = cc
        if not self.en:
            self.cc[ch] = cc

    def set_enabled(self, en):
        self.en = bool(en)
        if not self.en:
            self.top = self.ptop
            self.cc = [self.pcc[0], self.pcc[1]]

    def freq_hz(self):
        """What MicroPython's freq() reads back from DIV and TOP."""
        return slice_hz(self.div16 * (self.ptop + 1) // 2, self.div16 * (self.ptop + 1))


# -------------------------------------------------------------------- the chip
class Chip:
    """The RP2040 under MicroPython's rp2 port, on the caller's clock.

    Parameters
    ----------
    now_us : callable
        The present instant [us] on any origin, never going back.
    timer_us : int
        The value of the chip's microsecond timer at the present instant (the
        ticks start there; e.g. just below 2**30 to start near the wrap).
    """

    def __init__(self, now_us, timer_us=0):
        self.now_us = now_us
        self.listeners = []  # fn(t_us, kind, gpio, detail)
        self.history = {}  # gpio -> segments
        self.scheduler = None  # object with arm(timer, due_us) and cancel(timer)
        self.on_watchdog = None  # fn(): a watchdog reset is due (the user resets)
        self.adc_inputs = {}  # gpio 26..29 -> read_u16 at the true voltage (number or callable)
        self.adc_gain = 1.0  # every reading this many times the truth (a wrong reference)
        self.chip_temp_c = 27.0
        self.gpio_inputs = {}  # gpio -> level an outside circuit drives on an input
        self.scratch = [0] * 8
        self.reason = 0
        self.reset_log = []  # (t_us, kind)
        self.slices = [Slice(i) for i in range(8)]
        self.lock = _NoLock()  # the host's threads put a real lock here
        self._power(timer_us)

    # -- time
    def t_h(self):
        return int(round(self.now_us() * H_PER_US))

    def timer_us(self):
        """The chip's 64-bit microsecond timer (restarted by a chip reset)."""
        return int(self.now_us() - self.epoch_us)

    def ticks_us(self):
        return self.timer_us() & TICKS_MAX

    def ticks_ms(self):
        return (self.timer_us() // 1000) & TICKS_MAX

    # -- resets
    def _power(self, timer_us=0):
        t = self.t_h()
        self.epoch_us = self.now_us() - timer_us
        self.pads = {}  # gpio -> [function, sio out, sio output enable]
        for s in self.slices:
            s.power_on(t)
        self.freq_set = [False] * 8  # MicroPython's per-slice "freq was set"
        self.pwm_duty = {}  # gpio -> ("u16" | "ns", value) as MicroPython keeps it
        self.timers = []
        self.wdt_timeout_us = None
        self.wdt_due_us = None
        for g in list(self.history):
            self._emit(g, t)

    def reset(self, kind):
        """A reset at the present instant: "power" (everything cleared), "watchdog"
        (the chip resets, the watchdog's scratch registers and reason survive),
        "soft" (MicroPython restarts its VM: slices stopped, soft timers gone; pads,
        GPIO levels, the running watchdog and the ticks carry on)."""
        self._cancel_timers()
        if kind == "power":
            self.scratch = [0] * 8
            self.reason = 0
            self._power()
        elif kind == "watchdog":
            self.reason = 1
            self._power()
        elif kind == "soft":
            t = self.t_h()
            for s in self.slices:
                s.advance(t)
                s.set_enabled(False)
            self.freq_set = [False] * 8
            for g in list(self.history):
                self._emit(g, t)
        else:
            raise ValueError("reset kind: power, watchdog or soft")
        self.reset_log.append((self.now_us(), kind))
        self._notify("reset", None, {"kind": kind})

    # -- pads
    def pad(self, gpio):
        p = self.pads.get(gpio)
        if p is None:
            p = self.pads[gpio] = ["null", 0, False]
        return p

    def level(self, gpio):
        """The pad's level now (0 while it floats: the board's pull-down)."""
        t = self.t_h()
        lev = 0
        for seg in self.history.get(gpio, []):
            if seg[0] > t:
                break
            lev = level_at(seg, t)
        return lev

    def _segments(self, gpio, t):
        func, out, oe = self.pad(gpio)
        if func == "pwm" and isinstance(gpio, int):
            s = self.slices[(gpio >> 1) & 7]
            s.advance(t)
            return s.segments(gpio & 1)
        if func == "sio" and oe:
            return [[t, 0, 0, out]]
        return [[t, 0, 0, 0]]

    def _emit(self, gpio, t):
        h = self.history.get(gpio)
        if h is None:
            h = self.history[gpio] = []
        while h and h[-1][0] >= t:
            h.pop()  # a forecast (a latch at a wrap still to come) the write replaces
        for seg in self._segments(gpio, t):
            if h and _same_wave(h[-1], seg):
                continue
            h.append(seg)

    def _slice_changed(self, sl, t):
        for g in range(30):
            if (g >> 1) & 7 == sl and self.pads.get(g, ("null",))[0] == "pwm":
                self._emit(g, t)

    def _notify(self, kind, gpio, detail):
        if self.listeners:
            t = self.now_us()
            for fn in list(self.listeners):
                fn(t, kind, gpio, detail)

    def sio(self, gpio, func=None, out=None, oe=None):
        with self.lock:
            p = self.pad(gpio)
            if out is not None:
                p[1] = 1 if out else 0
            if oe is not None:
                p[2] = bool(oe)
            if func is not None:
                p[0] = func
            self._emit(gpio, self.t_h())
        if p[0] == "sio":
            self._notify("gpio", gpio, {"mode": "gpio", "value": p[1] if p[2] else 0})

    # -- PWM register writes (at the present instant)
    def pwm_write(self, sl, div16=None, top=None, cc=None, en=None):
        with self.lock:
            s = self.slices[sl]
            t = self.t_h()
            s.advance(t)
            if div16 is not None:
                s.write_div(div16)
            if top is not None:
                s.write_top(top)
            if cc is not None:
                s.write_cc(cc[0], cc[1])
            if en is not None:
                s.set_enabled(en)
            self._slice_changed(sl, t)

    # -- timers
    def arm(self, timer, due_us):
        if timer not in self.timers:
            self.timers.append(timer)
        if self.scheduler is not None:
            self.scheduler.arm(timer, due_us)

    def cancel(self, timer):
        if timer in self.timers:
            self.timers.remove(timer)
        if self.scheduler is not None:
            self.scheduler.cancel(timer)

    def _cancel_timers(self):
        for tm in list(self.timers):
            tm.alive = False
            self.cancel(tm)

    # -- watchdog
    def wdt_start(self, timeout_ms):
        self.wdt_timeout_us = timeout_ms * 1000
        self.wdt_feed()

    def wdt_feed(self):
        if self.wdt_timeout_us is not None:
            self.wdt_due_us = self.now_us() + self.wdt_timeout_us

    def wdt_expired(self):
        return self.wdt_due_us is not None and self.now_us() >= self.wdt_due_us

    # -- ADC
    def adc_read_u16(self, channel):
        if channel == ADC_TEMP_CHANNEL:
            return temp_sensor_u16(self.chip_temp_c, self.adc_gain)
        src = self.adc_inputs.get(ADC_FIRST_GPIO + channel, 0)
        value = src() if callable(src) else src
        return _u16_of_raw(_raw12(float(value) * self.adc_gain))

    # -- memory
    def mem32_read(self, addr):
        if addr == WATCHDOG_REASON:
            return self.reason
        i = (addr - WATCHDOG_SCRATCH0) >> 2
        if 0 <= i < 8 and addr & 3 == 0:
            return self.scratch[i]
        raise ValueError("mem32: address not modelled")

    def mem32_write(self, addr, value):
        i = (addr - WATCHDOG_SCRATCH0) >> 2
        if 0 <= i < 8 and addr & 3 == 0:
            self.scratch[i] = value & 0xFFFFFFFF
            return
        raise ValueError("mem32: address not modelled")

    # -- what the pads did
    def segments(self, gpio):
        return self.history.get(gpio, [])

    def edges_h(self, gpio, end_h, mean_below_h=0):
        """The pad's level changes [(t [h], level)] before end_h; a periodic
        segment faster than mean_below_h gives its mean level (a fraction)."""
        h = self.history.get(gpio, [])
        out = []
        cur = 0.0
        for i in range(len(h)):
            seg = h[i]
            a = seg[0]
            if a >= end_h:
                break
            b = min(h[i + 1][0] if i + 1 < len(h) else end_h, end_h)
            t, origin, period, high = seg
            lev = float(level_at(seg, a)) if period >= mean_below_h or period == 0 else high / period
            if lev != cur:
                out.append((a, lev))
                cur = lev
            if period == 0 or period < mean_below_h:
                continue
            k = (a - origin) // period
            while True:
                p0 = origin + k * period
                if p0 >= b:
                    break
                if p0 > a:
                    out.append((p0, 1.0))
                if a < p0 + high < b:
                    out.append((p0 + high, 0.0))
                k += 1
            cur = float(level_at(seg, b - 1))
        return out

    def pulses_us(self, gpio, end_us=None):
        """The pad's complete high intervals [(start [us], width [us])] up to
        end_us (default: now), expanded from its segments."""
        end_h = self.t_h() if end_us is None else int(round(end_us * H_PER_US))
        out = []
        rise = None
        for t, lev in self.edges_h(gpio, end_h):
            if lev and rise is None:
                rise = t
            elif not lev and rise is not None:
                out.append((rise / H_PER_US, (t - rise) / H_PER_US))
                rise = None
        return out

    def levels_us(self, gpio, end_us, mean_below_us=100.0):
        """The pad as [(from [us], level)] up to end_us: trains with a period of at
        least mean_below_us are exact pulses; a faster one (the standby bias) is
        its mean level, so hours of it stay cheap."""
        end_h = int(round(end_us * H_PER_US))
        return [(t / H_PER_US, lev) for t, lev in self.edges_h(gpio, end_h, int(mean_below_us * H_PER_US))]


class _NoLock:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
