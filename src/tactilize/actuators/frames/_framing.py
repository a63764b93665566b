"""The frame layer of the serial byte format: start byte, length, sequence, command, CRC.

Frame layout (all multi-byte integers big-endian)::

    +-------+-----+-----+-----+-------------------+---------+
    | START | LEN | SEQ | CMD | PAYLOAD (LEN B)   | CRC16   |
    | 0xA5  | u8  | u8  | u8  | 0 .. 64 bytes     | u16     |
    +-------+-----+-----+-----+-------------------+---------+

``CRC16`` is CRC-16/CCITT-FALSE (polynomial 0x1021, initial value 0xFFFF, no
reflection, no final XOR) over ``LEN SEQ CMD PAYLOAD``; the start byte is left out
so that a resynchronising receiver can check a candidate frame without knowing
where it began.  The firmware computes it bit by bit (MicroPython has no
``binascii.crc_hqx`` on every port, and a frame is at most 70 bytes); the host
uses a 256-entry table for the same value.
"""

from __future__ import annotations

import time
from enum import IntEnum
from typing import NamedTuple

#: the protocol version this host speaks (it also understands version 2 and 3 boards)
PROTOCOL_VERSION = 4
#: SENSE payload of a version 3 host: the reply then carries the faulty channels
SENSE_V3 = bytes((3,))

START = 0xA5
#: largest payload a frame may carry [bytes]; keeps a corrupted length byte from
#: making a receiver wait long for bytes that will never form a frame
MAX_PAYLOAD = 64
#: start, length, sequence, command
HEADER_SIZE = 4
#: header plus the two CRC bytes
OVERHEAD = HEADER_SIZE + 2


class Command(IntEnum):
    """Frame command codes (requests below 0x80, replies from 0x80)."""

    SET = 0x01
    STOP = 0x02
    HEARTBEAT = 0x03
    STATUS = 0x04
    HOLD = 0x05
    SENSE = 0x06
    PAIR = 0x07
    PING = 0x08
    EVENTS = 0x09
    ACK = 0x80
    NAK = 0x81
    STATUS_REPLY = 0x82
    SENSE_REPLY = 0x83
    PONG = 0x84


def command_name(command: int) -> str:
    """A command code's name for messages ("SET"), or its hex for an unknown one."""
    try:
        return Command(command).name
    except ValueError:
        return f"0x{command:02x}"


class NakReason(IntEnum):
    """Why the controller rejected a frame (first NAK payload byte)."""

    BAD_CHECKSUM = 1
    REFUSED_LIMIT = 2
    UNKNOWN_COMMAND = 3
    BAD_PAYLOAD = 4


class Refused(IntEnum):
    """Which hard limit a refused SET would have crossed (NAK detail byte)."""

    NONE = 0
    FREQUENCY = 1
    PULSE_WIDTH = 2
    DUTY = 3
    CHANNEL = 4
    ENERGY = 5


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
        table.append(crc)
    return tuple(table)


# A byte-wise table on the host (8x fewer Python steps than the bit loop the
# firmware uses; the tests check both give the same value).
_CRC_TABLE = _crc_table()


def crc16_ccitt(data: bytes | bytearray | memoryview, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (poly 0x1021, init 0xFFFF); check value of
    ``b"123456789"`` is 0x29B1."""
    table = _CRC_TABLE
    for byte in bytes(data):
        crc = ((crc << 8) & 0xFFFF) ^ table[(crc >> 8) ^ byte]
    return crc


class Frame(NamedTuple):
    """One decoded frame."""

    seq: int
    command: int
    payload: bytes


def encode_frame(seq: int, command: int, payload: bytes = b"") -> bytes:
    """The bytes of one frame.

    Parameters
    ----------
    seq : int
        Sequence number, taken modulo 256.
    command : int
        A :class:`Command` code (any byte is allowed, so tests can send unknown ones).
    payload : bytes
        At most :data:`MAX_PAYLOAD` bytes.
    """
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    if not 0 <= command <= 0xFF:
        raise ValueError(f"command {command} is not a byte")
    body = bytes((len(payload), seq & 0xFF, command)) + bytes(payload)
    return bytes((START,)) + body + crc16_ccitt(body).to_bytes(2, "big")


class FrameDecoder:
    """Finds frames in a byte stream that may hold garbage, partial and corrupt frames.

    Feed it whatever the port returned; it returns every complete valid frame.
    On a bad checksum or an impossible length it drops only the candidate start
    byte and rescans from the next byte, so a valid frame that followed (or was
    swallowed by) a corrupt header is still found.

    Attributes
    ----------
    crc_errors : int
        Candidate frames rejected for their checksum.
    discarded_bytes : int
        Bytes skipped while hunting for a start byte.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.crc_errors = 0
        self.discarded_bytes = 0
        #: monotonic time [s] at which the candidate frame now held back started
        #: waiting for its tail; None when nothing waits
        self.pending_since_s: float | None = None

    def __len__(self) -> int:
        """Bytes held back, waiting to complete a frame."""
        return len(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Frame]:
        """Add received bytes; return the frames they completed, in order."""
        self._buf.extend(data)
        frames: list[Frame] = []
        buf = self._buf
        while buf:
            if buf[0] != START:
                i = buf.find(START)
                skip = len(buf) if i < 0 else i
                self.discarded_bytes += skip
                del buf[:skip]
                continue
            if len(buf) < 2:
                break
            length = buf[1]
            if length > MAX_PAYLOAD:
                self._drop_start()
                continue
            total = OVERHEAD + length
            if len(buf) < total:
                break
            body = bytes(buf[1 : HEADER_SIZE + length])
            if crc16_ccitt(body) != int.from_bytes(buf[HEADER_SIZE + length : total], "big"):
                self.crc_errors += 1
                self._drop_start()
                continue
            frames.append(Frame(buf[2], buf[3], bytes(buf[HEADER_SIZE : HEADER_SIZE + length])))
            del buf[:total]
            self.pending_since_s = None
        if not buf:
            self.pending_since_s = None
        elif self.pending_since_s is None:
            self.pending_since_s = time.monotonic()
        return frames

    def expire_stale(self, max_age_s: float) -> list[Frame]:
        """:meth:`expire` when the held-back candidate has waited longer than
        ``max_age_s`` [s] (measured per candidate, so bytes that keep arriving
        behind a corrupt length byte do not keep it alive)."""
        if self.pending_since_s is not None and time.monotonic() - self.pending_since_s > max_age_s:
            return self.expire()
        return []

    def expire(self) -> list[Frame]:
        """Give up on a partial frame (call after a silence longer than a frame
        takes to arrive), so a corrupted length byte cannot hold later frames
        hostage; returns the frames that were held back behind it."""
        if not self._buf:
            return []
        self._drop_start()
        return self.feed(b"")

    def _drop_start(self) -> None:
        self.discarded_bytes += 1
        del self._buf[:1]
        self.pending_since_s = None


def decode_nak(payload: bytes) -> tuple[NakReason | int, Refused | int]:
    """(reason, detail) of a NAK payload; unknown codes come back as plain ints."""
    reason = payload[0] if payload else 0
    detail = payload[1] if len(payload) > 1 else 0
    try:
        reason = NakReason(reason)
    except ValueError:
        pass
    try:
        detail = Refused(detail)
    except ValueError:
        pass
    return reason, detail

#: flags bit: every output is off because the watchdog fired (cleared by a SET)
FLAG_WATCHDOG_TRIPPED = 0x01
#: flags bit (version 3): a channel's sense path is faulty; the board limits its
#: wire with the circuit's worst case until a measurement passes its checks
FLAG_SENSE_FAULT = 0x02
#: flags bit: the firmware caught an exception since the last STOP; it turned
#: every output off, took its wires' heat estimates to the budget and went on
FLAG_FIRMWARE_ERROR = 0x04

