# The tactile controller: MicroPython firmware for an RP2040 board (Raspberry Pi Pico).
#
# Flash it as the board's main.py (see docs/firmware.md).  It drives two actuator
# channels (one MOSFET gate each) with pulse trains, speaks the framed protocol of
# tactilize/actuators/protocol.py over the USB serial port (the REPL's
# stdin/stdout, raw bytes), acknowledges every valid frame, refuses any request
# beyond its own hard limits, and turns every output off when no valid frame has
# arrived for WATCHDOG_MS.
#
# The same file runs on the host: `tactilize controller-emulator` injects
# tactilize/firmware/host_machine.py as `machine` and feeds it a pseudo-terminal.
# So: MicroPython-compatible code only (no dataclasses, enum, typing, f-strings,
# annotations or bytearray.find), integer arithmetic in wire units, and every
# host difference confined to the small compatibility block below.
#
# This file keeps its own copy of the frame codec because a board runs one file;
# the tests run the host's protocol.py against it, so the two cannot drift.

import struct
import sys
import time

import machine

VERSION = 1

# ---------------------------------------------------------------- hardware map
# GPIO driving the gate of each channel's MOSFET (through ~100 ohm, with a
# 100 kohm pull-down so the gate is off while the pin floats during reset).
# GP16 and GP18 sit on different PWM slices (slice = (gpio >> 1) & 7): the two
# outputs of one slice share its frequency, so GP16/GP17 could not differ.
CHANNEL_PINS = (16, 18)
# Status LED: lit while any channel is on.
LED_PIN = "LED"
# Maintenance jumper: tie this pin to GND before power-up and main.py returns to
# the REPL at once, so mpremote can reach the board (the running controller
# disables Ctrl-C, since 0x03 is an ordinary byte in the binary protocol).
MAINTENANCE_PIN = 15

# ---------------------------------------------------------------- hard limits
# The controller's own limits, independent of any host.  They sit just outside
# the host's actuator limits (tactilize.mapping.ActuatorLimits: 1..300 Hz,
# 20 us..2 ms, duty 10 %) so a healthy host never meets them, and a broken or
# hostile host cannot overheat a wire.
MIN_FREQUENCY_MHZ = 1000  # 1 Hz
MAX_FREQUENCY_MHZ = 300000  # 300 Hz, the paper's top vibration frequency
MIN_WIDTH_NS = 10000  # 10 us
MAX_WIDTH_NS = 5000000  # 5 ms
MAX_DUTY_PPM = 200000  # 20 %: above ~10 % a 75 um wire leaves its transformation band
WATCHDOG_MS = 200
# A frame of at most 70 bytes takes well under a millisecond at USB speed; a
# partial frame older than this was corrupted, and waiting longer would let a
# bad length byte swallow the heartbeats and trip the watchdog.
FRAME_TIMEOUT_MS = 50
# How long the main loop waits for input before checking the watchdog [ms].
POLL_MS = 5
# Below this frequency the RP2040 PWM cannot make the period from an integer Hz
# setting accurately (MicroPython's PWM.freq takes integers; 0.5 Hz rounding is
# 2.5 % at 20 Hz), so slower trains use a soft timer and a busy-waited pulse.
PWM_MIN_FREQUENCY_MHZ = 20000

# ---------------------------------------------------------------- protocol
START = 0xA5
MAX_PAYLOAD = 64
CMD_SET = 0x01
CMD_STOP = 0x02
CMD_HEARTBEAT = 0x03
CMD_STATUS = 0x04
CMD_ACK = 0x80
CMD_NAK = 0x81
CMD_STATUS_REPLY = 0x82
NAK_BAD_CHECKSUM = 1
NAK_REFUSED_LIMIT = 2
NAK_UNKNOWN_COMMAND = 3
NAK_BAD_PAYLOAD = 4
REFUSED_NONE = 0
REFUSED_FREQUENCY = 1
REFUSED_WIDTH = 2
REFUSED_DUTY = 3
REFUSED_CHANNEL = 4
FLAG_WATCHDOG_TRIPPED = 0x01
SET_FORMAT = ">BIIH"
STATUS_FORMAT = ">BBIII" + "BIIH" * 2 + "IIIIIH"

# ---------------------------------------------------------------- host compatibility
# MicroPython's time has ticks_ms/ticks_diff/sleep_us; CPython has monotonic.
_ticks_ms = getattr(time, "ticks_ms", None)
_ticks_diff = getattr(time, "ticks_diff", None)
_sleep_us = getattr(time, "sleep_us", None)
if _ticks_ms is None:

    def _ticks_ms():
        return int(time.monotonic() * 1000)

    def _ticks_diff(a, b):
        return a - b

    def _sleep_us(us):
        # A busy wait, as on the board: time.sleep would overshoot short pulses.
        end = time.perf_counter() + us / 1e6
        while time.perf_counter() < end:
            pass


def crc16(data, crc=0xFFFF):
    """CRC-16/CCITT-FALSE over data (poly 0x1021, init 0xFFFF)."""
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            if crc & 0x8000:
                crc = ((crc << 1) ^ 0x1021) & 0xFFFF
            else:
                crc = (crc << 1) & 0xFFFF
    return crc


def encode_frame(seq, cmd, payload=b""):
    body = bytes((len(payload), seq & 0xFF, cmd)) + bytes(payload)
    return bytes((START,)) + body + struct.pack(">H", crc16(body))


class Decoder:
    """Splits a byte stream into frames; calls on_frame(seq, cmd, payload) for
    each valid one and on_bad(seq) for each with a bad checksum.  After any
    failure it drops just the candidate start byte and rescans, so a valid frame
    hidden behind garbage or a corrupt header is still found."""

    def __init__(self, on_frame, on_bad):
        self.buf = bytearray()
        self.on_frame = on_frame
        self.on_bad = on_bad
        # When the frame candidate now at buf[0] started waiting for its tail;
        # None while no candidate waits.  Measured per candidate, not from the
        # last byte received: heartbeats arriving behind a corrupt length byte
        # must not keep that candidate alive.
        self.pending_since_ms = None

    def feed(self, data):
        self.buf.extend(data)
        self._scan()

    def expire(self, now_ms):
        if self.pending_since_ms is not None and _ticks_diff(now_ms, self.pending_since_ms) > FRAME_TIMEOUT_MS:
            self.buf = self.buf[1:]
            self.pending_since_ms = None
            self._scan()

    def _scan(self):
        while self.buf:
            buf = self.buf
            if buf[0] != START:
                i = 1
                n = len(buf)
                while i < n and buf[i] != START:
                    i += 1
                self.buf = buf[i:]
                self.pending_since_ms = None
                continue
            if len(buf) < 2:
                break
            length = buf[1]
            if length > MAX_PAYLOAD:
                self.buf = buf[1:]
                self.pending_since_ms = None
                continue
            total = 6 + length
            if len(buf) < total:
                break
            self.pending_since_ms = None
            got = (buf[4 + length] << 8) | buf[5 + length]
            if crc16(buf[1 : 4 + length]) != got:
                self.buf = buf[1:]
                self.on_bad(buf[2])
                continue
            self.buf = buf[total:]
            self.on_frame(buf[2], buf[3], bytes(buf[4 : 4 + length]))
        if self.buf and self.pending_since_ms is None:
            self.pending_since_ms = _ticks_ms()


class Channel:
    """One actuator output: a PWM slice for fast trains, a soft timer for slow ones."""

    def __init__(self, index, pin_id):
        self.index = index
        self.pin_id = pin_id
        self.pin = machine.Pin(pin_id, machine.Pin.OUT, value=0)
        self.pwm = None
        self.timer = None
        self.frequency_mhz = 0
        self.width_ns = 0
        self.amplitude_q16 = 0

    @property
    def on(self):
        return self.frequency_mhz > 0

    def off(self):
        if self.timer is not None:
            self.timer.deinit()
            self.timer = None
        if self.pwm is not None:
            self.pwm.duty_ns(0)
            self.pwm.deinit()
            self.pwm = None
        # Take the pin back from the PWM slice and hold the gate low.
        self.pin = machine.Pin(self.pin_id, machine.Pin.OUT, value=0)
        self.frequency_mhz = 0
        self.width_ns = 0
        self.amplitude_q16 = 0

    def set(self, frequency_mhz, width_ns, amplitude_q16):
        """Start (or retune) the pulse train; the caller has checked the limits.
        Returns the frequency actually produced [mHz]."""
        if frequency_mhz >= PWM_MIN_FREQUENCY_MHZ:
            if self.timer is not None:
                self.timer.deinit()
                self.timer = None
            if self.pwm is None:
                self.pwm = machine.PWM(self.pin)
            hz = (frequency_mhz + 500) // 1000
            # Width first to 0 so that a lower frequency never briefly meets an
            # old, longer width (and a higher one never an impossible one).
            self.pwm.duty_ns(0)
            self.pwm.freq(hz)
            self.pwm.duty_ns(width_ns)
            applied_mhz = hz * 1000
        else:
            if self.pwm is not None:
                self.pwm.duty_ns(0)
                self.pwm.deinit()
                self.pwm = None
                self.pin = machine.Pin(self.pin_id, machine.Pin.OUT, value=0)
            if self.timer is not None:
                self.timer.deinit()
            period_ms = (1000000 + frequency_mhz // 2) // frequency_mhz
            self.width_ns = width_ns
            self.timer = machine.Timer(mode=machine.Timer.PERIODIC, period=period_ms, callback=self._pulse)
            applied_mhz = (1000000000 + period_ms * 500) // (period_ms * 1000)
        self.frequency_mhz = applied_mhz
        self.width_ns = width_ns
        self.amplitude_q16 = amplitude_q16
        return applied_mhz

    def _pulse(self, timer):
        # Soft-IRQ context on the board: the pulse is busy-waited so its width is
        # exact to a microsecond even though the timer's edge may jitter.
        pin = self.pin
        pin.value(1)
        _sleep_us(self.width_ns // 1000)
        pin.value(0)


class Controller:
    """The protocol state machine.

    write(bytes) sends to the host; on_change(channel, on, frequency_mhz,
    width_ns, reason), if given, is called whenever an output changes (the
    emulator prints it; the board lights its LED).
    """

    def __init__(self, write, on_change=None, pins=CHANNEL_PINS):
        self.write = write
        self.on_change = on_change
        self.channels = [Channel(i, p) for i, p in enumerate(pins)]
        try:
            self.led = machine.Pin(LED_PIN, machine.Pin.OUT, value=0)
        except (ValueError, TypeError):
            self.led = None
        self.decoder = Decoder(self._on_frame, self._on_bad)
        self.start_ms = _ticks_ms()
        self.last_valid_ms = self.start_ms
        self.watchdog_tripped = False
        self.frames_ok = 0
        self.frames_bad = 0
        self.running = True

    # -- input
    def feed(self, data):
        self.decoder.feed(data)

    def tick(self):
        """Called from the main loop at least every POLL_MS: watchdog and stale frames."""
        now = _ticks_ms()
        self.decoder.expire(now)
        if _ticks_diff(now, self.last_valid_ms) > WATCHDOG_MS:
            if any(ch.on for ch in self.channels):
                self.all_off("watchdog")
                self.watchdog_tripped = True

    # -- frames
    def _reply(self, seq, cmd, payload=b""):
        self.write(encode_frame(seq, cmd, payload))

    def _ack(self, seq, cmd):
        flags = FLAG_WATCHDOG_TRIPPED if self.watchdog_tripped else 0
        self._reply(seq, CMD_ACK, bytes((cmd, flags)))

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
            return self._ack(seq, cmd)
        if cmd == CMD_STATUS:
            return self._reply(seq, CMD_STATUS_REPLY, self.status_payload())
        return self._nak(seq, NAK_UNKNOWN_COMMAND)

    def _set(self, seq, payload):
        if len(payload) != struct.calcsize(SET_FORMAT):
            return self._nak(seq, NAK_BAD_PAYLOAD)
        index, f_mhz, w_ns, amp = struct.unpack(SET_FORMAT, payload)
        if index >= len(self.channels):
            return self._nak(seq, NAK_BAD_PAYLOAD, REFUSED_CHANNEL)
        ch = self.channels[index]
        if f_mhz == 0 or w_ns == 0 or amp == 0:
            if ch.on:
                ch.off()
                self._changed(ch, "command")
            self.watchdog_tripped = False
            return self._ack(seq, CMD_SET)
        refused = self.check_limits(f_mhz, w_ns)
        if refused:
            # Refused: the channel keeps its previous (valid) drive.
            return self._nak(seq, NAK_REFUSED_LIMIT, refused)
        before = (ch.frequency_mhz, ch.width_ns)
        ch.set(f_mhz, w_ns, amp)
        self.watchdog_tripped = False
        if (ch.frequency_mhz, ch.width_ns) != before:
            self._changed(ch, "command")
        return self._ack(seq, CMD_SET)

    @staticmethod
    def check_limits(f_mhz, w_ns):
        """0 when the drive is within the hard limits, else the REFUSED_* code."""
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
            FLAG_WATCHDOG_TRIPPED if self.watchdog_tripped else 0,
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


def run(read, controller):
    """The main loop: read(timeout_ms) returns received bytes (maybe empty)."""
    while controller.running:
        data = read(POLL_MS)
        if data:
            controller.feed(data)
        controller.tick()


class UsbSerial:
    """The board's USB CDC serial port as raw bytes (the REPL's stdin/stdout)."""

    def __init__(self):
        import select

        self.rx = getattr(sys.stdin, "buffer", sys.stdin)
        self.tx = getattr(sys.stdout, "buffer", sys.stdout)
        self.poller = select.poll()
        self.poller.register(sys.stdin, select.POLLIN)

    def read(self, timeout_ms):
        data = bytearray()
        if self.poller.poll(timeout_ms):
            # One byte per ready poll: stdin has no non-blocking bulk read.
            while len(data) < 128:
                data.extend(self.rx.read(1))
                if not self.poller.poll(0):
                    break
        return data

    def write(self, data):
        self.tx.write(data)


def main():
    if machine.Pin(MAINTENANCE_PIN, machine.Pin.IN, machine.Pin.PULL_UP).value() == 0:
        return
    try:
        import micropython

        # 0x03 (Ctrl-C) is a normal byte here: it must not interrupt the program.
        micropython.kbd_intr(-1)
    except ImportError:
        micropython = None
    port = UsbSerial()
    controller = Controller(port.write)
    try:
        run(port.read, controller)
    finally:
        controller.all_off("exit")
        if micropython is not None:
            micropython.kbd_intr(3)


if __name__ == "__main__":
    main()
