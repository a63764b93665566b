# One actuator channel of the tactile controller (MicroPython module, copied to
# the board next to main.py; see docs/firmware.md): its pulse train, its standby
# bias, and the gate that holds every pulse to the wire's running heat estimate
# (tactile_heat.py).
#
# Fast even trains run on a PWM slice; slow (< 20 Hz) and irregular ones place
# each pulse with a one-shot timer, as do the host's scheduled pulses (protocol
# version 4, tactile_events.py).  A changed drive never restarts a train: its
# first pulse starts at max(last start + new period, now, last end + 1 us), the
# host's PulseScheduler rule (tactilize.synthesis), so a host that resends its
# drive cannot multiply the pulse rate nor silence a slow train.
#
# MicroPython-compatible code only; on the host `machine` is host_machine.

import machine

try:
    import tactile_events as E
    import tactile_frames as F
    import tactile_wire as W
except ImportError:  # on the host, inside the package
    from tactilize.firmware import tactile_events as E
    from tactilize.firmware import tactile_frames as F
    from tactilize.firmware import tactile_wire as W

BIAS_HZ = 20000
# Below this frequency the RP2040 PWM cannot make the period from an integer Hz
# setting accurately (MicroPython's PWM.freq takes integers; 0.5 Hz rounding is
# 2.5 % at 20 Hz), so slower trains use timers and a busy-waited pulse.
PWM_MIN_FREQUENCY_MHZ = 20000
# A pulse the heat gate would cut below this [us] is left out.
GATE_MIN_US = 10
# The hardware watchdog once run() started it (fed also during a retune's wait).
WDT = [None]


def _irq_off():
    # The heat estimate is shared by the main loop and the timers' callbacks.
    f = getattr(machine, "disable_irq", None)
    return f() if f is not None else None


def _irq_on(state):
    f = getattr(machine, "enable_irq", None)
    if f is not None:
        f(state)


def plan(frequency_mhz, width_ns, regularity_q16):
    """What a drive runs as: (mode, applied frequency [mHz], period [us], jitter
    depth [periods]).  A PWM slice runs whole hertz; a timed train's period is
    rounded up, so it never runs faster than asked."""
    period_us = (1000000000 + frequency_mhz - 1) // frequency_mhz
    j = W.jitter_depth(regularity_q16, period_us, width_ns // 1000)
    if j <= 0 and frequency_mhz >= PWM_MIN_FREQUENCY_MHZ:
        hz = (frequency_mhz + 500) // 1000
        return "pwm", hz * 1000, 1000000 // hz, 0.0
    return "timed", (1000000000 + period_us // 2) // period_us, period_us, j


class Channel:
    """One actuator output: a PWM slice or timers for the pulses, a second slice
    for the standby bias, the sense path, the hold, and the heat estimate
    (``heat``; None: no gate, for bench use of the timing alone)."""

    def __init__(self, index, pin_id, bias_pin_id=None, sense=None, hold=None, heat=None):
        self.index = index
        self.pin_id = pin_id
        self.pin = machine.Pin(pin_id, machine.Pin.OUT, value=0)
        self.pwm = None
        self.pwm_duty_ns = 0
        self.timer = None
        self.mode = None
        self.request = None
        self.frequency_mhz = 0
        self.width_ns = 0
        self.amplitude_q16 = 0
        self.bias_pin_id = bias_pin_id
        self.bias_pwm = None
        self.bias_q16 = 0
        self.sense = sense
        self.hold = hold
        self.heat = heat
        self.p_w = 0.0  # bound on the heat while on [W], for the gate
        self.jitter_j = 0.0
        self.period_us = 0
        self.k = 0
        self.anchor_us = 0
        self.lead = 0.0
        self.gen = 0
        self.last_start_us = None
        self.last_end_us = None
        self.rng = W.Jitter(0x2545F491 + index)
        self.queue = E.EventQueue()

    @property
    def on(self):
        return self.frequency_mhz > 0

    @property
    def live(self):
        return self.frequency_mhz > 0 or self.bias_q16 > 0 or len(self.queue.pending) > 0

    def off(self):
        self._stop_train(F._ticks_us())
        self.queue.clear()
        self.pin = machine.Pin(self.pin_id, machine.Pin.OUT, value=0)
        self.mode = None
        self.request = None
        self.jitter_j = 0.0
        self.frequency_mhz = 0
        self.width_ns = 0
        self.amplitude_q16 = 0
        self.set_bias(0)
        if self.hold is not None:
            self.hold.clear()

    def set_bias(self, q16):
        """Standby bias: the switch chopped at BIAS_HZ, conducting q16 / 65536 of the time."""
        if self.bias_pin_id is None:
            return
        if q16 <= 0:
            if self.bias_pwm is not None:
                self.bias_pwm.duty_u16(0)
                self.bias_pwm.deinit()
                self.bias_pwm = None
                machine.Pin(self.bias_pin_id, machine.Pin.OUT, value=0)
            self.bias_q16 = 0
        else:
            if self.bias_pwm is None:
                self.bias_pwm = machine.PWM(machine.Pin(self.bias_pin_id))
                self.bias_pwm.duty_u16(0)
                self.bias_pwm.freq(BIAS_HZ)
            q16 = min(q16, 65535)
            self.bias_pwm.duty_u16(q16)
            self.bias_q16 = q16
        self._heat_changed(F._ticks_us())

    def set(self, frequency_mhz, width_ns, amplitude_q16, regularity_q16=W.REGULARITY_EVEN):
        """Start or change the pulse train (the caller checked the limits at the
        frequency plan() says runs).  Returns that frequency [mHz]."""
        mode, applied, period_us, j = plan(frequency_mhz, width_ns, regularity_q16)
        now = F._ticks_us()
        was_on = self.on
        self.queue.clear()  # a train replaces the scheduled pulses
        self.width_ns = width_ns
        self.amplitude_q16 = amplitude_q16
        self.request = (frequency_mhz, width_ns, amplitude_q16, regularity_q16)
        if mode == "pwm":
            self._cancel_timer()
            self.mode = "pwm"
            self.frequency_mhz = applied
            self._pwm(applied // 1000, now)
        else:
            if self.mode == "pwm":
                self._stop_train(now)
            self._cancel_timer()
            # The host's PulseScheduler rule: never sooner than a period after
            # the last start, never on top of the last pulse.
            delay = 0
            if self.last_start_us is not None:
                delay = max(0, F._ticks_diff(self.last_start_us, now) + period_us,
                            F._ticks_diff(self.last_end_us, now) + 1)
            self.mode = "timed"
            self.period_us, self.jitter_j, self.k = period_us, j, 0
            # Pulse 0's jitter only delays it, and not at all after silence.
            self.lead = 1.0 if was_on and self.last_start_us is not None else 0.0
            self.anchor_us = F._ticks_add(now, delay)
            self.frequency_mhz = applied
            self._arm()
        self._heat_changed(now)
        return applied

    def set_width(self, width_ns):
        """The hold's new width [ns] for the running train (no restart)."""
        self.width_ns = width_ns
        if self.request is not None:
            r = self.request
            self.request = (r[0], width_ns, r[2], r[3])
        now = F._ticks_us()
        if self.mode == "pwm":
            self._gate_pwm(now)
        self._heat_changed(now)

    def service(self, now_us, p_w):
        """Called by the main loop: the bound on the heat while on [W] now, the
        heat estimate brought up to date, a PWM train held while it would not fit."""
        self.p_w = p_w
        if self.mode == "pwm":
            self._gate_pwm(now_us)
        self._heat_changed(now_us)

    # -- the PWM slice

    def _pwm(self, hz, now):
        if self.pwm is None:
            # A fresh slice: its output is low until the first wrap latches these.
            self.pwm = machine.PWM(self.pin)
            self.pwm.duty_ns(0)
            self.pwm_duty_ns = 0
            self.pwm.freq(hz)
        elif self.pwm.freq() != hz:
            # The RP2040 applies a new divider at once but TOP and compare at
            # the wrap (docs/references.md, section 8 (PWM retune)): a pulse in
            # flight would stretch.  So: compare 0, wait one old period (a wrap
            # latches the 0 and the last pulse ends), then the new divider and
            # TOP, and the new compare latches with TOP at the next wrap.
            old_us = 1000000 // self.pwm.freq()
            self.pwm.duty_ns(0)
            self.pwm_duty_ns = 0
            F._sleep_us(old_us + 50)
            if WDT[0] is not None:
                WDT[0].feed()  # a train of retunes in one pass must not reset the chip
            self.pwm.freq(hz)
        self._gate_pwm(now)

    def _gate_pwm(self, now):
        # A PWM pulse lands on the wire as the estimate stands (its train is
        # counted as a mean heat, which bounds each period's lowest temperature).
        pwm = self.pwm
        if pwm is None:
            return  # no slice, no train to gate (mode "pwm" always has one)
        want = self.width_ns
        if self.heat is not None:
            state = _irq_off()
            fits = self.heat.room_j(now) >= self.width_ns * 1e-9 * self.p_w
            _irq_on(state)
            if not fits:
                want = 0
        if want != self.pwm_duty_ns:
            pwm.duty_ns(want)  # same divider and TOP: latches at the wrap
            self.pwm_duty_ns = want
            if want == 0:
                self._mark(now, self.width_ns // 1000)

    def _mark(self, now, us):
        # A PWM pulse may have just started: count it as the last one.
        self.last_start_us = now
        self.last_end_us = F._ticks_add(now, us)

    # -- timed trains

    def _cancel_timer(self):
        self.gen += 1
        if self.timer is not None:
            self.timer.deinit()
            self.timer = None

    def _stop_train(self, now):
        self._cancel_timer()
        if self.pwm is not None:
            if self.pwm_duty_ns > 0:
                self._mark(now, self.pwm_duty_ns // 1000)
            self.pwm.duty_ns(0)
            self.pwm.deinit()
            self.pwm = None
            self.pwm_duty_ns = 0
            self.pin = machine.Pin(self.pin_id, machine.Pin.OUT, value=0)

    def _arm(self):
        # Pulse k: (k + j u_k) periods after the train's start; the anchor moves
        # on by a period per pulse (ticks_add takes at most 2^29 us at a time).
        now = F._ticks_us()
        P = self.period_us
        if self.k > 0:
            # A timer that fired late (a busy board) catches up, but with no two
            # pulses closer than max(0.4, 0.9 - j) periods (never closer than the
            # jitter itself brings neighbours), and skips what it missed by more
            # than two periods rather than running a burst.
            while F._ticks_diff(now, self.anchor_us) > 2 * P:
                self.anchor_us = F._ticks_add(self.anchor_us, P)
        u = self.rng.next() if self.jitter_j > 0 else 0.0
        if self.k == 0:
            u = max(u, 0.0) * self.lead
        due = F._ticks_add(self.anchor_us, int(self.jitter_j * u * P))
        if self.k > 0 and self.last_start_us is not None:
            earliest = F._ticks_add(self.last_start_us, int(max(0.4, 0.9 - self.jitter_j) * P))
            if F._ticks_diff(due, earliest) < 0:
                due = earliest
        delay = max(1, F._ticks_diff(due, now))
        gen = self.gen
        self.timer = machine.Timer(mode=machine.Timer.ONE_SHOT, freq=1000000.0 / delay,
                                   callback=lambda t: self._due(gen))

    def _due(self, gen):
        if gen != self.gen or self.mode != "timed":
            return
        self._fire()
        self.k += 1
        self.anchor_us = F._ticks_add(self.anchor_us, self.period_us)
        self._arm()

    def _fire(self):
        self._pulse(F._ticks_us(), self.width_ns // 1000)

    def _pulse(self, now, us):
        # Soft-IRQ context on the board: the pulse is busy-waited so its width is
        # exact to a microsecond even though the timer's edge may jitter; the
        # sense path is read in the middle of it.  Returns the width fired [us]
        # (0: the heat estimate left it out).
        if self.heat is not None:
            state = _irq_off()
            room = self.heat.room_j(now)
            if us * 1e-6 * self.p_w > room:
                us = int(room / self.p_w * 1e6)
            if us >= GATE_MIN_US:
                self.heat.add(now, us * 1e-6 * self.p_w)
            _irq_on(state)
            if us < GATE_MIN_US:
                return 0
        self.last_start_us = now
        self.last_end_us = F._ticks_add(now, us)
        pin = self.pin
        pin.value(1)
        F._sleep_us(us // 2)
        if self.sense is not None:
            self.sense.sample(F._ticks_ms())
        F._sleep_us(us - us // 2)
        pin.value(0)
        return us

    # -- scheduled pulses (protocol version 4)

    def play(self, now, due_of, entries):
        """The host's pulses from now on (tactile_events.EventQueue.replace with
        ``due_of(offset)`` their ticks), replacing those not yet fired; a train stops."""
        # The timer first, outside the lock: on the host, deinit waits for a
        # callback that may itself be waiting for the lock.
        self._cancel_timer()
        state = _irq_off()
        if self.mode != "events":
            if self.mode == "pwm":
                self._stop_train(now)
            self.mode = "events"
            self.request = None
            self.frequency_mhz = 0
            self.width_ns = 0
            self.jitter_j = 0.0
        self.queue.replace(now, due_of, entries, F._ticks_diff)
        self._arm_event()
        _irq_on(state)
        self._heat_changed(now)

    def stop_events(self):
        """No more scheduled pulses (a SET with nothing to play)."""
        if self.mode == "events":
            self._cancel_timer()
            state = _irq_off()
            self.queue.clear()
            self.mode = None
            _irq_on(state)

    def _arm_event(self):
        if not self.queue.pending:
            return
        delay = F._ticks_diff(self.queue.pending[0][0], F._ticks_us()) - E.EARLY_US
        gen = self.gen
        self.timer = machine.Timer(mode=machine.Timer.ONE_SHOT, freq=1000000.0 / max(1, delay),
                                   callback=lambda t: self._event_due(gen))

    def _event_due(self, gen):
        state = _irq_off()
        if gen != self.gen or self.mode != "events" or not self.queue.pending:
            _irq_on(state)
            return
        due, _, us = self.queue.pop()
        _irq_on(state)
        wait = F._ticks_diff(due, F._ticks_us())
        if wait > 0:
            F._sleep_us(wait)
        self._fire_event(us)
        state = _irq_off()
        if gen == self.gen:
            self._arm_event()
        _irq_on(state)

    def _fire_event(self, us):
        # Never two starts closer than MIN_GAP_US, and a pulse leaves at least
        # half the time since the last start to cool (the SET's duty rule).
        q = self.queue
        now = F._ticks_us()
        asked = us
        if self.last_start_us is not None:
            gap = F._ticks_diff(now, self.last_start_us)
            if gap < E.MIN_GAP_US:
                q.count(E.SKIPPED)
                return
            if us > gap // 2:
                us = gap // 2
        fired = self._pulse(now, us)
        if fired <= 0:
            q.count(E.SKIPPED)
            return
        q.count(E.FIRED)
        if fired < asked:
            q.count(E.SHORTENED)

    def _heat_changed(self, now):
        if self.heat is None:
            return
        mean = self.bias_q16 / 65536.0
        if self.mode == "pwm" and self.pwm_duty_ns > 0:
            mean += self.frequency_mhz * 1e-3 * self.pwm_duty_ns * 1e-9
        state = _irq_off()
        self.heat.set_power(now, mean * self.p_w)
        _irq_on(state)
