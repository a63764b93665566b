# The tactile controller: MicroPython firmware for an RP2040 board (Raspberry Pi Pico).
#
# Flash it as the board's main.py (see docs/firmware.md).  It drives two actuator
# channels (one MOSFET gate each) with pulse trains, speaks the framed protocol of
# tactilize/actuators/frames/ over the USB serial port (the REPL's
# stdin/stdout, raw bytes), acknowledges every valid frame, refuses any request
# beyond its own hard limits, and turns every output off when no valid frame has
# arrived for WATCHDOG_MS.
#
# The same file runs on the host: `tactilize controller-emulator` injects
# tactilize/boardhost/host_machine.py as `machine` and feeds it a pseudo-terminal.
# So: MicroPython-compatible code only (no dataclasses, enum, typing, f-strings,
# annotations or bytearray.find), integer arithmetic in wire units, and every
# host difference confined to the small compatibility block below.
#
# This file keeps its own copy of the frame codec (MicroPython has no enum or
# dataclasses); the tests run the host's frames package against it, so the two
# cannot drift.  The wire's physics on the board (energy limits, self-sensing,
# the hold between host messages) is in tactile_wire.py, each channel's pulses in
# tactile_channel.py and the running heat estimate that gates them in
# tactile_heat.py, all copied next to it.

import struct

import machine

try:
    import tactile_channel as C
    import tactile_events as E
    import tactile_frames as F
    import tactile_heat as H
    import tactile_wire as W
except ImportError:  # on the host, inside the package
    from tactilize.firmware import tactile_channel as C
    from tactilize.firmware import tactile_events as E
    from tactilize.firmware import tactile_frames as F
    from tactilize.firmware import tactile_heat as H
    from tactilize.firmware import tactile_wire as W

# The codec and the clock (tactile_frames.py), under the names this file uses.
START, MAX_PAYLOAD, FRAME_TIMEOUT_MS = F.START, F.MAX_PAYLOAD, F.FRAME_TIMEOUT_MS
crc16, encode_frame, Decoder = F.crc16, F.encode_frame, F.Decoder
_ticks_ms, _ticks_diff, _ticks_us, _sleep_us = F._ticks_ms, F._ticks_diff, F._ticks_us, F._sleep_us
_ticks_add = F._ticks_add

# 3: the sense-fault flag (ACK and STATUS flags bit 1; a per-channel byte after
# SENSE_REPLY's fields when the SENSE carries the host's version, 3).
# 4: scheduled pulses (EVENTS) and the board's clock (PING/PONG), tactile_events.py.
# A host reads the version from STATUS (docs/firmware.md).
VERSION = 4

# ---------------------------------------------------------------- hardware map
# GPIO driving the gate of each channel's MOSFET (through ~100 ohm, with a
# 100 kohm pull-down so the gate is off while the pin floats during reset).
# GP16 and GP18 sit on different PWM slices (slice = (gpio >> 1) & 7): the two
# outputs of one slice share its frequency, so GP16/GP17 could not differ.
CHANNEL_PINS = (16, 18)
# GPIO of each channel's standby bias: a 20 kHz PWM on a slice of its own (GP20:
# slice 2, GP22: slice 3), OR-ed with the pulse pin into the gate (docs/hardware.md).
BIAS_PINS = (20, 22)
BIAS_HZ = C.BIAS_HZ
# ADC inputs: each channel's current-sense amplifier, and the wire rail's divider.
SENSE_ADC_PINS = (26, 27)
RAIL_ADC_PIN = 28
# Status LED: lit while any channel is on.
LED_PIN = "LED"
# Maintenance jumper: tie this pin to GND before power-up and main.py returns to
# the REPL at once, so mpremote can reach the board (the running controller
# disables Ctrl-C, since 0x03 is an ordinary byte in the binary protocol).
MAINTENANCE_PIN = 15

# ---------------------------------------------------------------- hard limits
# The controller's own limits, independent of any host.  The shape limits sit
# outside the host's actuator limits; the heat is limited in energy terms by
# tactile_wire.WireLimits (the host's safety envelope, evaluated on the board for
# the wire and circuit stored on it), so a broken or hostile host cannot overheat
# a wire with any sequence of valid frames.
MIN_FREQUENCY_MHZ = 1000  # 1 Hz
MAX_FREQUENCY_MHZ = 300000  # 300 Hz, the paper's top vibration frequency
MIN_WIDTH_NS = 10000  # 10 us
MAX_WIDTH_NS = 5000000  # 5 ms
MAX_DUTY_PPM = 500000  # a pulse leaves half its period to cool; heat: the energy limits
WATCHDOG_MS = 200
# machine.WDT: a hung VM resets the chip (every pin back to an input, the gates
# pulled low) this long after the main loop last ran [ms].
WDT_TIMEOUT_MS = 100
# How often the board's hold loop runs [ms].
HOLD_MS = 10
# How long the main loop waits for input before checking the watchdog [ms].
POLL_MS = 5
Channel = C.Channel
# How often the chip's temperature is read [ms].
TEMP_MS = 1000

# ---------------------------------------------------------------- protocol
CMD_SET = 0x01
CMD_STOP = 0x02
CMD_HEARTBEAT = 0x03
CMD_STATUS = 0x04
CMD_HOLD = 0x05
CMD_SENSE = 0x06
CMD_PAIR = 0x07
CMD_PING = 0x08
CMD_EVENTS = 0x09
CMD_ACK = 0x80
CMD_NAK = 0x81
CMD_STATUS_REPLY = 0x82
CMD_SENSE_REPLY = 0x83
CMD_PONG = 0x84
NAK_BAD_CHECKSUM = 1
NAK_REFUSED_LIMIT = 2
NAK_UNKNOWN_COMMAND = 3
NAK_BAD_PAYLOAD = 4
REFUSED_NONE = 0
REFUSED_FREQUENCY = 1
REFUSED_WIDTH = 2
REFUSED_DUTY = 3
REFUSED_CHANNEL = 4
REFUSED_ENERGY = 5
FLAG_WATCHDOG_TRIPPED = 0x01
FLAG_SENSE_FAULT = 0x02
# An exception was caught in the firmware since the last STOP: every output went
# off and the heat estimates went to the budget, and the loop went on.
FLAG_FIRMWARE_ERROR = 0x04
SET_FORMAT = ">BIIH"
STATUS_FORMAT = ">BBIII" + "BIIH" * 2 + "IIIIIH"
HOLD_FORMAT = ">BIII"  # channel, pulse heat [nJ], bias heat [uW], target resistance [uohm]
PAIR_FORMAT = ">I" + "IIH" * 2  # onset offset of channel 1 [us], then (mHz, ns, amplitude) per channel
# rail [mV]; per channel R [uohm], I [uA], bias q16, width [ns], count; then, for
# a host that asked with version 3, the channels whose sense path is faulty (bit i)
SENSE_FORMAT = ">H" + "IIHIH" * 2

# The hardware watchdog once run() started it (fed also after each retune wait).
_wdt = C.WDT


class Controller:
    """The protocol state machine.

    write(bytes) sends to the host; on_change(channel, on, frequency_mhz,
    width_ns, reason), if given, is called whenever an output changes (the
    emulator prints it; the board lights its LED).

    Every board starts with its wires' estimates at the budget (tactile_heat.py):
    it cannot know how long it was off.  ``assume_cold`` is for the host's
    simulations of a board that has been idle for longer than that; main()
    never sets it and no frame can.
    """

    def __init__(self, write, on_change=None, pins=CHANNEL_PINS, bias_pins=BIAS_PINS, store="",
                 assume_cold=False):
        self.write = write
        self.on_change = on_change
        self.errors = 0
        self.error_flag = False
        # The wire and circuit stored on the board; the host cannot change them.
        self.config = W.parse_config(W.read_text(store + W.CONFIG_FILE), W.DEFAULT_CONFIG)
        self.limits = W.WireLimits(self.config)
        self.store = store
        cal = W.load_calibration(W.read_text(store + W.CAL_FILE), len(pins))
        self.channels = []
        for i, p in enumerate(pins):
            # Every gate low before anything that may fail below.
            bias_pin = bias_pins[i] if bias_pins is not None and i < len(bias_pins) else None
            heat = H.HeatEstimate(self.config, _ticks_diff, not assume_cold)
            ch = Channel(i, p, bias_pin, None, W.Hold(self.limits, self.config), heat, self._channel_error)
            ch.p_w = self.limits.p_max
            self.channels.append(ch)
        rail = machine.ADC(RAIL_ADC_PIN)
        for i, ch in enumerate(self.channels):
            ch.sense = W.Sense(machine.ADC(SENSE_ADC_PINS[i % 2]), rail, cal[i][0], cal[i][1], self.config)
        try:
            temp_adc = machine.ADC(H.TEMP_ADC)
        except (ValueError, TypeError, OSError):
            temp_adc = None
        self.air = H.Air(self.config, temp_adc)
        self._read_temperature()
        try:
            self.led = machine.Pin(LED_PIN, machine.Pin.OUT, value=0)
        except (ValueError, TypeError):
            self.led = None
        self.decoder = Decoder(self._on_frame, self._on_bad)
        self.clock = E.BoardClock(_ticks_us, _ticks_diff)
        self.start_ms = _ticks_ms()
        self.last_valid_ms = self.start_ms
        self.hold_ms = self.start_ms
        self.pair_timer = None
        self.watchdog_tripped = False
        self.frames_ok = 0
        self.frames_bad = 0
        self.running = True

    # -- input
    def feed(self, data):
        try:
            self.decoder.feed(data)
        except Exception as exc:
            self.fail(exc)

    def tick(self):
        """Called from the main loop at least every POLL_MS: watchdog, stale
        frames, the chip's temperature, the sense readings and the hold."""
        try:
            self._tick()
        except Exception as exc:
            self.fail(exc)

    def fail(self, exc):
        """Whatever raised: every output off, every estimate at its budget, the
        decoder cleared; the loop goes on and the next reply carries
        FLAG_FIRMWARE_ERROR (a STOP clears it)."""
        self.errors = (self.errors + 1) & 0xFFFFFFFF
        self.error_flag = True
        for ch in self.channels:
            ch.fail()
        timer, self.pair_timer = self.pair_timer, None
        self.decoder = Decoder(self._on_frame, self._on_bad)
        try:
            if timer is not None:
                timer.deinit()
            self._changed(self.channels[0], "error")
        except Exception:
            pass  # the outputs are off already

    def _channel_error(self, exc):
        # A timer's callback failed on one channel: the whole board goes safe.
        self.fail(exc)

    def _read_temperature(self):
        """The budget for the air the chip's sensor shows (tactile_heat.Air)."""
        self.temp_ms = _ticks_ms()
        self.limits.budget = budget = self.air.budget_k()
        for ch in self.channels:
            ch.heat.set_budget(budget)

    def _tick(self):
        now = _ticks_ms()
        self.clock.now(_ticks_us())  # carried forward before the ticks wrap
        self.decoder.expire(now)
        if _ticks_diff(now, self.last_valid_ms) > WATCHDOG_MS:
            if any(ch.live for ch in self.channels) or self.pair_timer is not None:
                self.all_off("watchdog")
                self.watchdog_tripped = True
        if _ticks_diff(now, self.temp_ms) >= TEMP_MS:
            self._read_temperature()
        now_us = _ticks_us()
        for ch in self.channels:
            if ch.live:
                for _ in range(8):
                    ch.sense.sample(now)
            ch.service(now_us, self.limits.power(ch.sense.current_bound_a(now, _ticks_diff)))
        dt_ms = _ticks_diff(now, self.hold_ms)
        if dt_ms >= HOLD_MS:
            self.hold_ms = now
            for ch in self.channels:
                if ch.hold.active:
                    self._hold(ch, now, dt_ms / 1000.0)

    def _hold(self, ch, now, dt_s):
        """Keep the host's heat between its messages: width and bias from the
        measured heat while on, within the energy limits (tactile_wire.Hold)."""
        ch.hold.frequency_hz = ch.frequency_mhz / 1000.0
        sense = ch.sense
        width_s, bias = ch.hold.step(
            sense.resistance_ohm, sense.power_w(now, _ticks_diff), dt_s, ch.width_ns / 1e9,
            sense.current_bound_a(now, _ticks_diff),
        )
        if ch.on and width_s > 0:
            w_ns = int(width_s * 1e9)
            if w_ns < MIN_WIDTH_NS:
                w_ns = MIN_WIDTH_NS if self._fits(ch, ch.frequency_mhz, MIN_WIDTH_NS, bias) else 0
            if w_ns == 0:
                ch.off()
                self._changed(ch, "limit")
                return
            w_ns = min(w_ns, MAX_WIDTH_NS)
            if abs(w_ns - ch.width_ns) * 50 > ch.width_ns:  # more than 2 %
                ch.set_width(w_ns)
                self._changed(ch, "hold")
        ch.set_bias(int(bias * 65536))

    def _fits(self, ch, f_mhz, w_ns, bias, j=0.0):
        """The energy limits (tactile_wire.WireLimits) with the channel's heat while
        on, for a train of jitter depth j [periods]."""
        p = self.limits.power(ch.sense.current_bound_a(_ticks_ms(), _ticks_diff))
        return self.limits.allowed(f_mhz / 1000.0, w_ns / 1e9, bias, p, j)

    # -- frames
    def _reply(self, seq, cmd, payload=b""):
        self.write(encode_frame(seq, cmd, payload))

    def flags(self):
        flags = FLAG_WATCHDOG_TRIPPED if self.watchdog_tripped else 0
        if self.sense_faults():
            flags |= FLAG_SENSE_FAULT
        if self.error_flag:
            flags |= FLAG_FIRMWARE_ERROR
        return flags

    def sense_faults(self):
        """Bit i set: channel i's sense path is faulty (its limits use the worst case)."""
        bits = 0
        for ch in self.channels:
            if ch.sense.fault:
                bits |= 1 << ch.index
        return bits

    def _ack(self, seq, cmd):
        self._reply(seq, CMD_ACK, bytes((cmd, self.flags())))

    def _nak(self, seq, reason, detail=REFUSED_NONE):
        self._reply(seq, CMD_NAK, bytes((reason, detail)))

    def _on_bad(self, seq):
        self.frames_bad = (self.frames_bad + 1) & 0xFFFFFFFF
        self._nak(seq, NAK_BAD_CHECKSUM)

    def _on_frame(self, seq, cmd, payload):
        # Any frame with a good checksum proves the host is alive.
        self.last_valid_ms = _ticks_ms()
        self.frames_ok = (self.frames_ok + 1) & 0xFFFFFFFF
        if cmd == CMD_HEARTBEAT:
            if payload:
                return self._nak(seq, NAK_BAD_PAYLOAD)
            return self._ack(seq, cmd)
        if cmd == CMD_SET:
            return self._set(seq, payload)
        if cmd == CMD_STOP:
            self.all_off("stop")
            self.watchdog_tripped = False
            ack = self._ack(seq, cmd)  # says what happened, once more
            self.error_flag = False
            return ack
        if cmd == CMD_STATUS:
            return self._reply(seq, CMD_STATUS_REPLY, self.status_payload())
        if cmd == CMD_SENSE:
            # A host of version 3 asks with its version and gets the faults too;
            # an older host's empty SENSE gets the reply it knows.
            if len(payload) > 1:
                return self._nak(seq, NAK_BAD_PAYLOAD)
            return self._reply(seq, CMD_SENSE_REPLY, self.sense_payload(len(payload) == 1 and payload[0] >= 3))
        if cmd == CMD_HOLD:
            return self._hold_cmd(seq, payload)
        if cmd == CMD_PAIR:
            return self._pair(seq, payload)
        if cmd == CMD_PING:
            return self._ping(seq, payload)
        if cmd == CMD_EVENTS:
            return self._events(seq, payload)
        return self._nak(seq, NAK_UNKNOWN_COMMAND)

    def _ping(self, seq, payload):
        pong = E.pong(payload, self.clock.now(), [ch.queue for ch in self.channels])
        return self._nak(seq, NAK_BAD_PAYLOAD) if pong is None else self._reply(seq, CMD_PONG, pong)

    def _events(self, seq, payload):
        """A channel's scheduled pulses (tactile_events.py): replaces those not yet fired."""
        parsed = E.parse(payload, len(self.channels), MIN_WIDTH_NS // 1000, MAX_WIDTH_NS // 1000)
        if parsed == 2:
            return self._nak(seq, NAK_REFUSED_LIMIT, REFUSED_WIDTH)
        if parsed == 3:
            return self._nak(seq, NAK_BAD_PAYLOAD, REFUSED_CHANNEL)
        if parsed == 1:
            return self._nak(seq, NAK_BAD_PAYLOAD)
        index, base, entries = parsed
        now = _ticks_us()
        ahead = E.signed32(base - self.clock.now(now))
        if ahead > E.MAX_AHEAD_US:
            return self._nak(seq, NAK_BAD_PAYLOAD)
        ch = self.channels[index]
        if index == 1:
            self._cancel_pair()
        was_on = ch.on
        self.watchdog_tripped = False
        # Starts relative to now: a base far behind makes them late, never a
        # tick sum out of ticks_add's range.
        ch.play(now, [(eid, ahead + off, w) for eid, off, w in entries])
        if was_on:
            self._changed(ch, "events")
        return self._ack(seq, CMD_EVENTS)

    def _set(self, seq, payload):
        reg = W.REGULARITY_EVEN
        if len(payload) == struct.calcsize(SET_FORMAT) + 2:  # with a regularity
            reg = struct.unpack(">H", payload[-2:])[0]
            payload = payload[:-2]
        if len(payload) != struct.calcsize(SET_FORMAT):
            return self._nak(seq, NAK_BAD_PAYLOAD)
        index, f_mhz, w_ns, amp = struct.unpack(SET_FORMAT, payload)
        if index >= len(self.channels):
            return self._nak(seq, NAK_BAD_PAYLOAD, REFUSED_CHANNEL)
        ch = self.channels[index]
        if index == 1:
            self._cancel_pair()
        refused = self._refused(ch, f_mhz, w_ns, amp, reg)
        if refused:
            # Refused: the channel keeps its previous (valid) drive.
            return self._nak(seq, NAK_REFUSED_LIMIT, refused)
        # The host resends freely: the same drive again changes nothing.
        if ch.request != (f_mhz, w_ns, amp, reg):
            self._apply(ch, f_mhz, w_ns, amp, reg)
        return self._ack(seq, CMD_SET)

    def _refused(self, ch, f_mhz, w_ns, amp, reg=W.REGULARITY_EVEN):
        """0 when a drive may run on a channel (off always may), else REFUSED_*."""
        if f_mhz == 0 or w_ns == 0 or amp == 0:
            return REFUSED_NONE
        refused = self.check_limits(f_mhz, w_ns)
        if refused:
            return refused
        # The heat of what runs: whole hertz on a PWM slice, and a jittered
        # train's closest pulses.  The pulses come first: the bias is cut to the
        # room they leave (_apply).
        applied, _, j = C.plan(f_mhz, w_ns, reg)
        if not self._fits(ch, max(f_mhz, applied), w_ns, 0.0, j):
            return REFUSED_ENERGY
        return REFUSED_NONE

    def _apply(self, ch, f_mhz, w_ns, amp, reg=W.REGULARITY_EVEN):
        self.watchdog_tripped = False
        if f_mhz == 0 or w_ns == 0 or amp == 0:
            ch.stop_events()
            if ch.on:
                bias, hold = ch.bias_q16, ch.hold
                keep = (hold.frequency_hz, hold.energy_j, hold.bias_w, hold.target_ohm)
                ch.off()
                # Texture off: the standby bias and the hold stay.
                hold.set(0.0, 0.0, keep[2], keep[3])
                ch.set_bias(bias)
                self._changed(ch, "command")
            return
        before = (ch.frequency_mhz, ch.width_ns)
        p = self.limits.power(ch.sense.current_bound_a(_ticks_ms(), _ticks_diff))
        applied, _, j = C.plan(f_mhz, w_ns, reg)
        room = self.limits.max_bias(max(f_mhz, applied) / 1000.0, w_ns / 1e9, p, j)
        ch.p_w = p
        if ch.bias_q16 > int(room * 65536):
            ch.set_bias(int(room * 65536))
        ch.set(f_mhz, w_ns, amp, reg)
        if (ch.frequency_mhz, ch.width_ns) != before:
            self._changed(ch, "command")

    def _hold_cmd(self, seq, payload):
        if len(payload) != struct.calcsize(HOLD_FORMAT):
            return self._nak(seq, NAK_BAD_PAYLOAD)
        index, e_nj, bias_uw, target_uohm = struct.unpack(HOLD_FORMAT, payload)
        if index >= len(self.channels):
            return self._nak(seq, NAK_BAD_PAYLOAD, REFUSED_CHANNEL)
        ch = self.channels[index]
        f = ch.frequency_mhz / 1000.0
        if not self.limits.heat_allowed(f, e_nj * 1e-9, bias_uw * 1e-6):
            return self._nak(seq, NAK_REFUSED_LIMIT, REFUSED_ENERGY)
        self.watchdog_tripped = False
        ch.hold.set(f, e_nj * 1e-9, bias_uw * 1e-6, target_uohm * 1e-6)
        if not ch.hold.active:
            ch.set_bias(0)
        else:
            self._hold(ch, _ticks_ms(), 0.0)
        return self._ack(seq, CMD_HOLD)

    def _pair(self, seq, payload):
        """Both channels at once, channel 1 starting soa_us after channel 0 (timed
        here, for apparent movement between the two pins)."""
        if len(payload) != struct.calcsize(PAIR_FORMAT):
            return self._nak(seq, NAK_BAD_PAYLOAD)
        if len(self.channels) < 2:
            return self._nak(seq, NAK_BAD_PAYLOAD, REFUSED_CHANNEL)
        v = struct.unpack(PAIR_FORMAT, payload)
        soa_us, d0, d1 = v[0], v[1:4], v[4:7]
        ch0, ch1 = self.channels[0], self.channels[1]
        for ch, d in ((ch0, d0), (ch1, d1)):
            refused = self._refused(ch, d[0], d[1], d[2])
            if refused:
                return self._nak(seq, NAK_REFUSED_LIMIT, refused)
        even = W.REGULARITY_EVEN
        if self.pair_timer is None and ch0.request == d0 + (even,) and ch1.request == d1 + (even,):
            return self._ack(seq, CMD_PAIR)  # a resent PAIR changes nothing
        self._cancel_pair()
        self._apply(ch0, d0[0], d0[1], d0[2])
        self._apply(ch1, 0, 0, 0)
        if soa_us == 0:
            self._apply(ch1, d1[0], d1[1], d1[2])
        else:

            def start(timer):
                self.pair_timer = None
                try:
                    self._apply(ch1, d1[0], d1[1], d1[2])
                except Exception as exc:
                    self.fail(exc)

            self.pair_timer = machine.Timer(mode=machine.Timer.ONE_SHOT, period=soa_us, tick_hz=C.TIMER_HZ,
                                            callback=start)
        return self._ack(seq, CMD_PAIR)

    def _cancel_pair(self):
        if self.pair_timer is not None:
            self.pair_timer.deinit()
            self.pair_timer = None

    @staticmethod
    def check_limits(f_mhz, w_ns):
        """0 when the drive's shape is within the hard limits, else the REFUSED_*
        code (the heat is checked by the energy limits)."""
        if f_mhz < MIN_FREQUENCY_MHZ or f_mhz > MAX_FREQUENCY_MHZ:
            return REFUSED_FREQUENCY
        if w_ns < MIN_WIDTH_NS or w_ns > MAX_WIDTH_NS:
            return REFUSED_WIDTH
        # duty = f * w = (f_mhz / 1e3) * (w_ns / 1e9); compare in integers.
        if f_mhz * w_ns > MAX_DUTY_PPM * 1000000:
            return REFUSED_DUTY
        return REFUSED_NONE

    # -- outputs
    def all_off(self, reason):
        self._cancel_pair()
        for ch in self.channels:
            if ch.on:
                ch.off()
                self._changed(ch, reason)
            else:
                ch.off()

    def _changed(self, ch, reason):
        if self.led is not None:
            self.led.value(1 if any(c.on for c in self.channels) else 0)
        if self.on_change is not None:
            self.on_change(ch.index, ch.on, ch.frequency_mhz, ch.width_ns, reason)

    def status_payload(self):
        fields = [
            VERSION,
            self.flags(),
            _ticks_diff(_ticks_ms(), self.start_ms) & 0xFFFFFFFF,
            self.frames_ok,
            self.frames_bad,
        ]
        for i in range(2):
            if i < len(self.channels):
                ch = self.channels[i]
                fields += [1 if ch.on else 0, ch.frequency_mhz, ch.width_ns, ch.amplitude_q16]
            else:
                fields += [0, 0, 0, 0]
        fields += [MIN_FREQUENCY_MHZ, MAX_FREQUENCY_MHZ, MIN_WIDTH_NS, MAX_WIDTH_NS, MAX_DUTY_PPM, WATCHDOG_MS]
        return struct.pack(STATUS_FORMAT, *fields)

    def sense_payload(self, faults=True):
        rail = 0
        fields = []
        for i in range(2):
            if i < len(self.channels):
                ch = self.channels[i]
                s = ch.sense
                rail = max(rail, int(s.rail_v * 1000))
                fields += [int(s.resistance_ohm * 1e6), int(s.current_a * 1e6), ch.bias_q16, ch.width_ns, s.count]
            else:
                fields += [0, 0, 0, 0, 0]
        if faults:
            return struct.pack(SENSE_FORMAT + "B", min(rail, 0xFFFF), *(fields + [self.sense_faults() & 0xFF]))
        return struct.pack(SENSE_FORMAT, min(rail, 0xFFFF), *fields)


def run(read, controller, wdt=None):
    """The main loop: read(timeout_ms) returns received bytes (maybe empty);
    wdt (machine.WDT) is fed once per pass, so a hung loop resets the chip."""
    _wdt[0] = wdt
    while controller.running:
        if wdt is not None:
            wdt.feed()
        data = read(POLL_MS)
        if data:
            controller.feed(data)
        controller.tick()


def main():
    if machine.Pin(MAINTENANCE_PIN, machine.Pin.IN, machine.Pin.PULL_UP).value() == 0:
        return
    try:
        import micropython

        # 0x03 (Ctrl-C) is a normal byte here: it must not interrupt the program.
        micropython.kbd_intr(-1)
    except ImportError:
        micropython = None
    port = F.UsbSerial()
    controller = Controller(port.write)
    # The hardware watchdog: cannot be stopped once started, so never in
    # maintenance mode (the jumper above returned already).
    wdt = machine.WDT(timeout=WDT_TIMEOUT_MS)
    try:
        run(port.read, controller, wdt)
    finally:
        controller.all_off("exit")
        if micropython is not None:
            micropython.kbd_intr(3)


if __name__ == "__main__":
    main()
