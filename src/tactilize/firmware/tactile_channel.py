# One actuator channel of the tactile controller (MicroPython module, copied to
# the board next to main.py; see docs/firmware.md): its pulse train, its standby
# bias, and the gate that holds every pulse to the wire's running heat estimate
# (tactile_heat.py).
#
# Every pulse on a gate pin is placed by a one-shot timer and busy-waited, and
# passes the heat gate first: trains even and irregular, and the host's
# scheduled pulses (protocol version 4, tactile_events.py).  No PWM slice drives
# a gate pin, because a slice carries its counter, compare and TOP over from
# before (deinit() and PWM() keep the counter; TOP and compare latch only at a
# wrap): a slice left near its wrap emits a pulse no gate saw (docs/references.md,
# section 10 (PWM slice)).  Only the 20 kHz standby bias uses a slice, and
# what it can carry over (one bias period) is counted.  A changed drive never restarts a train: its
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
# One bias period [us]: the longest a bias slice can go on at its old compare
# after a change (the compare latches at the wrap), or at what it held before a
# soft reset once it is enabled again (machine_pwm_deinit_all stops the slice
# mid-period; this firmware only ever runs the bias slices at BIAS_HZ).
BIAS_PERIOD_US = 1000000 // BIAS_HZ
# A pulse older than this [us] is forgotten: no rule looks further back than a
# period (at most 1 s), and MicroPython's ticks wrap at 2^30 us, so a remembered
# tick older than 2^29 us would read as a time in the future.
STALE_US = 10000000
# Timers are armed in microseconds: a period in ticks of this rate is exact,
# where freq= goes through the port's single-precision float and truncates
# (docs/references.md, section 10 (timer period)).
TIMER_HZ = 1000000
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
    """What a drive runs as: (applied frequency [mHz], period [ns], jitter depth
    [periods]).  The period is rounded up to the nanosecond and the train's
    anchor carries the fraction of a microsecond from pulse to pulse, so a
    train runs at the frequency asked (to 1 mHz), never faster."""
    period_ns = (1000000000000 + frequency_mhz - 1) // frequency_mhz
    j = W.jitter_depth(regularity_q16, (period_ns + 999) // 1000, width_ns // 1000)
    return (1000000000000 + period_ns // 2) // period_ns, period_ns, j


class Channel:
    """One actuator output: timers for the pulses on a GPIO, a PWM slice for the
    standby bias, the sense path, the hold, and the heat estimate (``heat``;
    None: no gate, for bench use of the timing alone).  ``on_error``, if given,
    is called with the exception when a timer's callback fails (the channel is
    already off and its estimate at the budget)."""

    def __init__(self, index, pin_id, bias_pin_id=None, sense=None, hold=None, heat=None, on_error=None):
        self.index = index
        self.pin_id = pin_id
        # A GPIO low before anything else: a pad a soft reset left on a slice
        # goes back to the pin's own level.
        self.pin = machine.Pin(pin_id, machine.Pin.OUT, value=0)
        self.on_error = on_error
        self.error = None
        self.timer = None
        self.mode = None
        self.request = None
        self.frequency_mhz = 0
        self.width_ns = 0
        self.amplitude_q16 = 0
        self.bias_pin_id = bias_pin_id
        if bias_pin_id is not None:
            machine.Pin(bias_pin_id, machine.Pin.OUT, value=0)
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
        self.period_ns = 0
        self.carry_ns = 0
        self.due_us = 0
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
        self._cancel_timer()
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

    def fail(self, exc=None):
        """Outputs off whatever state the channel is in, the estimate at its budget."""
        self.gen += 1
        for step in (self._cancel_timer, self.queue.clear):
            try:
                step()
            except Exception:
                pass
        try:
            self.pin = machine.Pin(self.pin_id, machine.Pin.OUT, value=0)
        except Exception:
            pass
        try:
            self.set_bias(0)
        except Exception:
            if self.bias_pin_id is not None:
                machine.Pin(self.bias_pin_id, machine.Pin.OUT, value=0)
            self.bias_pwm = None
            self.bias_q16 = 0
        self.mode = None
        self.request = None
        self.frequency_mhz = 0
        self.width_ns = 0
        self.amplitude_q16 = 0
        if self.hold is not None:
            self.hold.clear()
        if self.heat is not None:
            self.heat.assume_hot()
        if exc is not None:
            self.error = exc

    def _guard(self, fn):
        # A timer's callback runs outside the main loop: whatever it raises, the
        # channel goes off and the controller hears of it (no exception may stop
        # the board with a gate high).
        try:
            fn()
        except Exception as exc:
            self.fail(exc)
            if self.on_error is not None:
                self.on_error(exc)

    def set_bias(self, q16):
        """Standby bias: the switch chopped at BIAS_HZ, conducting q16 / 65536 of the time.

        The slice is made once and then only its compare changes: a new compare
        latches at the wrap, so the old level may run one more bias period,
        which the estimate counts as a pulse."""
        if self.bias_pin_id is None:
            return
        q16 = 0 if q16 <= 0 else min(q16, 65535)
        if q16 == self.bias_q16 and (q16 == 0 or self.bias_pwm is not None):
            return
        now = F._ticks_us()
        carry = self.bias_q16
        if self.bias_pwm is None:
            if q16 == 0:
                return
            # freq and a zero compare before the pad is switched to the slice
            # (MicroPython's PWM() selects the pad last); the slice then runs on
            # from wherever it stopped: at most one period at what it held.
            self.bias_pwm = machine.PWM(machine.Pin(self.bias_pin_id), freq=BIAS_HZ, duty_u16=0)
            carry = 65535
        self.bias_pwm.duty_u16(q16)
        self.bias_q16 = q16
        if self.heat is not None and carry > 0:
            state = _irq_off()
            self.heat.add(now, carry / 65536.0 * BIAS_PERIOD_US * 1e-6 * self.p_w)
            _irq_on(state)
        self._heat_changed(now)

    def set(self, frequency_mhz, width_ns, amplitude_q16, regularity_q16=W.REGULARITY_EVEN):
        """Start or change the pulse train (the caller checked the limits at the
        frequency plan() says runs).  Returns that frequency [mHz]."""
        applied, period_ns, j = plan(frequency_mhz, width_ns, regularity_q16)
        period_us = (period_ns + 999) // 1000
        now = F._ticks_us()
        was_on = self.on
        self.queue.clear()  # a train replaces the scheduled pulses
        self.width_ns = width_ns
        self.amplitude_q16 = amplitude_q16
        self.request = (frequency_mhz, width_ns, amplitude_q16, regularity_q16)
        self._cancel_timer()
        # The host's PulseScheduler rule: never sooner than a period after
        # the last start, never on top of the last pulse.
        self.forget_stale(now)
        delay = 0
        if self.last_start_us is not None:
            delay = max(0, F._ticks_diff(self.last_start_us, now) + period_us,
                        F._ticks_diff(self.last_end_us, now) + 1)
        self.mode = "timed"
        self.period_us, self.jitter_j, self.k = period_us, j, 0
        self.period_ns, self.carry_ns = period_ns, 0
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

    def service(self, now_us, p_w):
        """Called by the main loop: the bound on the heat while on [W] now, the
        heat estimate brought up to date, ticks too old to compare forgotten."""
        self.p_w = p_w
        self.forget_stale(now_us)
        self._heat_changed(now_us)

    def forget_stale(self, now_us):
        """Forget the last pulse once it is STALE_US old (before the ticks wrap)."""
        if self.last_start_us is not None:
            if not (0 <= F._ticks_diff(now_us, self.last_start_us) <= STALE_US):
                self.last_start_us = None
                self.last_end_us = None

    # -- timed trains

    def _cancel_timer(self):
        self.gen += 1
        if self.timer is not None:
            self.timer.deinit()
            self.timer = None

    def _arm(self):
        # Pulse k: (k + j u_k) periods after the train's start; the anchor moves
        # on by a period per pulse.
        now = F._ticks_us()
        P = self.period_us
        if self.k > 0:
            # A timer that fired late (a busy board) catches up, but with no two
            # pulses closer than max(0.4, 0.9 - j) periods (never closer than the
            # jitter itself brings neighbours), and skips what it missed by more
            # than two periods rather than running a burst.
            late = F._ticks_diff(now, self.anchor_us)
            if late > 2 * P:
                self.anchor_us = F._ticks_add(now, -(P + late % P))
        u = self.rng.next() if self.jitter_j > 0 else 0.0
        if self.k == 0:
            u = max(u, 0.0) * self.lead
        due = F._ticks_add(self.anchor_us, int(self.jitter_j * u * P))
        if self.k > 0 and self.last_start_us is not None:
            earliest = F._ticks_add(self.last_start_us, int(max(0.4, 0.9 - self.jitter_j) * P))
            if F._ticks_diff(due, earliest) < 0:
                due = earliest
        # Armed early and the rest busy-waited, as the scheduled pulses: the
        # pulse starts on its microsecond whatever the timer's grain (a timer
        # made from a frequency may fire a microsecond early or late).
        self.due_us = due
        delay = max(1, F._ticks_diff(due, now) - E.EARLY_US)
        gen = self.gen
        self.timer = machine.Timer(mode=machine.Timer.ONE_SHOT, period=delay, tick_hz=TIMER_HZ,
                                   callback=lambda t: self._guard(lambda: self._due(gen)))

    def _due(self, gen):
        if gen != self.gen or self.mode != "timed":
            return
        wait = F._ticks_diff(self.due_us, F._ticks_us())
        if wait > 0:
            F._sleep_us(wait)
        self._fire()
        self.k += 1
        self.carry_ns += self.period_ns
        step_us = self.carry_ns // 1000
        self.carry_ns -= step_us * 1000
        self.anchor_us = F._ticks_add(self.anchor_us, step_us)
        self._arm()

    def _fire(self):
        self._pulse(F._ticks_us(), self.width_ns // 1000)

    def _pulse(self, now, us):
        # Soft-IRQ context on the board: the pulse is busy-waited so its width is
        # exact to a microsecond even though the timer's edge may jitter; the
        # sense path is read in the middle of it.  This is the only place a
        # gate pin goes high.  Returns the width fired [us] (0: the heat
        # estimate left it out).
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
        try:
            pin.value(1)
            F._sleep_us(us // 2)
            if self.sense is not None:
                self.sense.sample(F._ticks_ms())
            F._sleep_us(us - us // 2)
        finally:
            pin.value(0)
        return us

    # -- scheduled pulses (protocol version 4)

    def play(self, now, rel_entries):
        """The host's pulses from now on (tactile_events.EventQueue.replace:
        ``rel_entries`` as (id, start after now [us], width [us])), replacing
        those not yet fired; a train stops."""
        # The timer first, outside the lock: on the host, deinit waits for a
        # callback that may itself be waiting for the lock.
        self._cancel_timer()
        state = _irq_off()
        if self.mode != "events":
            self.mode = "events"
            self.request = None
            self.frequency_mhz = 0
            self.width_ns = 0
            self.jitter_j = 0.0
        self.queue.replace(now, rel_entries, F._ticks_add)
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
        self.timer = machine.Timer(mode=machine.Timer.ONE_SHOT, period=max(1, delay), tick_hz=TIMER_HZ,
                                   callback=lambda t: self._guard(lambda: self._event_due(gen)))

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
            if 0 <= gap < E.MIN_GAP_US:
                q.count(E.SKIPPED)
                return
            if 0 <= gap and us > gap // 2:
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
        state = _irq_off()
        self.heat.set_power(now, self.bias_q16 / 65536.0 * self.p_w)
        _irq_on(state)
