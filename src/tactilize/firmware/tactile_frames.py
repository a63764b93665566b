# The frame codec and the USB serial port of the tactile controller (MicroPython module, copied to the
# board next to main.py; see controller.py).  The tests run the host's
# tactilize/actuators/frames/ against it, so the two cannot drift.

import struct
import time

START = 0xA5
MAX_PAYLOAD = 64
# A frame of at most 70 bytes takes well under a millisecond at USB speed; a
# partial frame older than this was corrupted, and waiting longer would let a
# bad length byte swallow the heartbeats and trip the watchdog.
FRAME_TIMEOUT_MS = 50

# ---------------------------------------------------------------- host compatibility
# MicroPython's time has ticks_ms/ticks_diff/sleep_us; CPython has monotonic.  The
# host's stand-ins are picked by getattr's default (not defined under an `if`), so
# mypy sees one callable per name on both.


def _host_ticks_add(a, b):
    return a + b


def _host_ticks_us():
    return int(time.monotonic() * 1000000)


def _host_ticks_ms():
    return int(time.monotonic() * 1000)


def _host_ticks_diff(a, b):
    return a - b


def _host_sleep_us(us):
    # A busy wait, as on the board: time.sleep would overshoot short pulses.
    # sleep(0) hands the GIL over at every turn: otherwise a pulse on one
    # channel's timer thread holds the other's up to the 5 ms switch interval,
    # where a board's two timers would each run on time.
    end = time.perf_counter() + us / 1e6
    while time.perf_counter() < end:
        time.sleep(0)


_ticks_ms = getattr(time, "ticks_ms", _host_ticks_ms)
_ticks_diff = getattr(time, "ticks_diff", _host_ticks_diff)
_sleep_us = getattr(time, "sleep_us", _host_sleep_us)
_ticks_us = getattr(time, "ticks_us", _host_ticks_us)
_ticks_add = getattr(time, "ticks_add", _host_ticks_add)


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


def _raw(stream):
    # The byte stream under a text one, where the port has it; a port without
    # .buffer reads and writes bytes-like str on the stream itself.
    return getattr(stream, "buffer", stream)


class UsbSerial:
    """The board's USB CDC serial port as raw bytes (the REPL's stdin/stdout)."""

    def __init__(self):
        import select
        import sys

        self.rx = _raw(sys.stdin)
        self.tx = _raw(sys.stdout)
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
