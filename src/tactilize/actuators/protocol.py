"""The framed binary protocol between the host and the tactile controller.

Pure functions and plain data, no I/O and no pyserial: the host's
:class:`~tactilize.actuators.serial.SerialOutput` uses it, tests fuzz it, and the
firmware (``tactilize/firmware/controller.py``) speaks the same bytes.

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

Commands, host to controller:

========  ====  ==========================================================
SET       0x01  channel u8, frequency u32 [mHz], width u32 [ns], amplitude u16
                (65535 = 1.0), then optionally regularity u16 (65535 = an even
                train, the default; lower: the pulses jitter around the same
                mean frequency, as tactilize.synthesis does).  Frequency, width
                or amplitude 0 turns it off.
STOP      0x02  no payload: every channel off.
HEARTBEAT 0x03  no payload: keeps the controller's 200 ms watchdog from firing.
STATUS    0x04  no payload: the controller answers with a STATUS_REPLY.
HOLD      0x05  channel u8, pulse heat u32 [nJ], bias heat u32 [uW], target
                resistance u32 [uohm]: the heat the board keeps between host
                messages (pulse width and bias from its measured I^2 R).
SENSE     0x06  no payload, or (version 3) the host's version u8: the controller
                answers with a SENSE_REPLY (with the faulty channels when asked
                with version 3).
PAIR      0x07  onset offset u32 [us], then frequency, width, amplitude of
                channels 0 and 1: channel 1 starts that long after channel 0.
========  ====  ==========================================================

Replies, controller to host (``SEQ`` echoes the sequence number of the frame
they answer, so the host can match replies to requests):

============  ====  ====================================================
ACK           0x80  command u8 (the command acknowledged), flags u8 (see
                    :data:`FLAG_WATCHDOG_TRIPPED`, :data:`FLAG_SENSE_FAULT`)
NAK           0x81  reason u8, detail u8 (see :class:`NakReason`, :class:`Refused`)
STATUS_REPLY  0x82  see :data:`STATUS_FORMAT` and :class:`ControllerStatus`
SENSE_REPLY   0x83  see :data:`SENSE_FORMAT` and :class:`SenseReport`
============  ====  ====================================================

Every command is idempotent, so the host may resend a frame whose ACK got lost:
a SET (or PAIR) equal to the one running changes nothing on the board.

Versions (STATUS_REPLY's first byte): 2, and 3, which adds the sense-fault flag
(bit 1 of the ACK and STATUS flags) and, when a SENSE carries the host's version
(:data:`SENSE_V3`), one byte after SENSE_REPLY's fields, bit ``i`` set when
channel ``i``'s sense path is faulty; an empty SENSE gets the version 2 reply, so
older hosts keep working with newer boards.  The host learns the board's version
from the STATUS reply of its handshake and asks with its version only then;
:func:`decode_sense` reads both lengths (``faults`` is None for version 2).
Wire units are integers (millihertz, nanoseconds) because the firmware works in
integers; :func:`encode_set_channel` converts from SI.

The firmware carries its own minimal copy of the codec (a board runs one file,
``main.py``, and MicroPython lacks ``dataclasses`` and ``enum``); the tests run
this module against that copy over a pseudo-terminal so they cannot drift apart.
"""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

__all__ = [
    "command_name",
    "START",
    "MAX_PAYLOAD",
    "HEADER_SIZE",
    "OVERHEAD",
    "Command",
    "NakReason",
    "Refused",
    "Frame",
    "FrameDecoder",
    "crc16_ccitt",
    "encode_frame",
    "encode_set_channel",
    "decode_set_channel",
    "SetChannel",
    "ControllerStatus",
    "ChannelStatus",
    "decode_status",
    "encode_status",
    "decode_nak",
    "STATUS_FORMAT",
    "SENSE_FORMAT",
    "encode_hold",
    "encode_pair",
    "ChannelSense",
    "SenseReport",
    "decode_sense",
    "AMPLITUDE_FULL_SCALE",
    "FLAG_WATCHDOG_TRIPPED",
    "FLAG_SENSE_FAULT",
    "PROTOCOL_VERSION",
    "SENSE_V3",
]

#: the protocol version this host speaks (it also understands version 2 boards)
PROTOCOL_VERSION = 3
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
#: the u16 amplitude that means 1.0 (the paper's full pulse height H)
AMPLITUDE_FULL_SCALE = 0xFFFF


class Command(IntEnum):
    """Frame command codes (requests below 0x80, replies from 0x80)."""

    SET = 0x01
    STOP = 0x02
    HEARTBEAT = 0x03
    STATUS = 0x04
    HOLD = 0x05
    SENSE = 0x06
    PAIR = 0x07
    ACK = 0x80
    NAK = 0x81
    STATUS_REPLY = 0x82
    SENSE_REPLY = 0x83


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


# ----------------------------------------------------------------- payloads

_SET_FORMAT = ">BIIH"
_SET_IRREGULAR_FORMAT = ">BIIHH"
#: regularity u16 of an even train (also what a SET without the field means)
REGULARITY_EVEN = 0xFFFF


class SetChannel(NamedTuple):
    """A SET payload in wire units."""

    channel: int
    frequency_mhz: int
    pulse_width_ns: int
    amplitude_q16: int
    regularity_q16: int = REGULARITY_EVEN

    @property
    def frequency_hz(self) -> float:
        return self.frequency_mhz / 1e3

    @property
    def pulse_width_s(self) -> float:
        return self.pulse_width_ns / 1e9

    @property
    def amplitude(self) -> float:
        return self.amplitude_q16 / AMPLITUDE_FULL_SCALE


def _u32(value: float, name: str) -> int:
    n = int(round(value))
    if not 0 <= n <= 0xFFFFFFFF:
        raise ValueError(f"{name} {value} does not fit the wire format")
    return n


def encode_set_channel(
    channel: int, frequency_hz: float, pulse_width_s: float, amplitude: float, regularity: float | None = None
) -> bytes:
    """SET payload from SI values.

    Parameters
    ----------
    channel : int
        Channel index, 0 or 1 on the pen's controller.
    frequency_hz : float
        Pulse frequency [Hz], sent in millihertz.
    pulse_width_s : float
        Pulse width [s], sent in nanoseconds.
    amplitude : float
        Fraction of full pulse height in [0, 1], sent as u16.
    regularity : float, optional
        The drive's regularity in [0, 1]; None or 1 sends the short frame (an
        even train), which every controller understands.
    """
    if not 0 <= channel <= 0xFF:
        raise ValueError(f"channel {channel} is not a byte")
    if not 0.0 <= amplitude <= 1.0:
        raise ValueError(f"amplitude {amplitude} outside [0, 1]")
    head = struct.pack(
        _SET_FORMAT,
        channel,
        _u32(frequency_hz * 1e3, "frequency_hz"),
        _u32(pulse_width_s * 1e9, "pulse_width_s"),
        int(round(amplitude * AMPLITUDE_FULL_SCALE)),
    )
    if regularity is None or regularity >= 1.0:
        return head
    if not 0.0 <= regularity < 1.0:
        raise ValueError(f"regularity {regularity} outside [0, 1]")
    return head + struct.pack(">H", min(REGULARITY_EVEN - 1, int(round(regularity * REGULARITY_EVEN))))


def decode_set_channel(payload: bytes) -> SetChannel:
    """Inverse of :func:`encode_set_channel` (wire units)."""
    if len(payload) == struct.calcsize(_SET_IRREGULAR_FORMAT):
        return SetChannel(*struct.unpack(_SET_IRREGULAR_FORMAT, payload))
    return SetChannel(*struct.unpack(_SET_FORMAT, payload))


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


#: STATUS_REPLY payload: version, flags, uptime [ms], frames accepted, frames
#: rejected; per channel (two) on, frequency [mHz], width [ns], amplitude u16;
#: hard limits: min and max frequency [mHz], min and max width [ns], max duty
#: [parts per million]; watchdog timeout [ms]
STATUS_FORMAT = ">BBIII" + "BIIH" * 2 + "IIIIIH"
#: flags bit: every output is off because the watchdog fired (cleared by a SET)
FLAG_WATCHDOG_TRIPPED = 0x01
#: flags bit (version 3): a channel's sense path is faulty; the board limits its
#: wire with the circuit's worst case until a measurement passes its checks
FLAG_SENSE_FAULT = 0x02


@dataclass(frozen=True)
class ChannelStatus:
    """What one channel of the controller is doing (SI units)."""

    on: bool
    frequency_hz: float
    pulse_width_s: float
    amplitude: float


@dataclass(frozen=True)
class ControllerStatus:
    """A STATUS_REPLY, in SI units.

    Attributes
    ----------
    version : int
        Firmware protocol version.
    watchdog_tripped : bool
        Every output is off because no valid frame came for ``watchdog_s``.
    uptime_s : float
        Time since the controller started [s].
    frames_ok, frames_bad : int
        Valid frames handled, and frames rejected for checksum (mod 2**32).
    channels : tuple of ChannelStatus
    min_frequency_hz, max_frequency_hz : float
        The controller's own hard frequency limits [Hz] (0 Hz, off, is always allowed).
    min_pulse_width_s, max_pulse_width_s : float
        Hard width limits [s].
    max_duty_ratio : float
        Hard duty-ratio limit (frequency times width).
    watchdog_s : float
        Silence after which the controller turns everything off [s].
    """

    version: int
    watchdog_tripped: bool
    uptime_s: float
    frames_ok: int
    frames_bad: int
    channels: tuple[ChannelStatus, ...]
    min_frequency_hz: float
    max_frequency_hz: float
    min_pulse_width_s: float
    max_pulse_width_s: float
    max_duty_ratio: float
    watchdog_s: float
    sense_fault: bool = False


def decode_status(payload: bytes) -> ControllerStatus:
    """A :class:`ControllerStatus` from a STATUS_REPLY payload."""
    v = struct.unpack(STATUS_FORMAT, payload)
    chans = tuple(
        ChannelStatus(bool(v[5 + 4 * i]), v[6 + 4 * i] / 1e3, v[7 + 4 * i] / 1e9, v[8 + 4 * i] / AMPLITUDE_FULL_SCALE)
        for i in range(2)
    )
    return ControllerStatus(
        version=v[0],
        watchdog_tripped=bool(v[1] & FLAG_WATCHDOG_TRIPPED),
        uptime_s=v[2] / 1e3,
        frames_ok=v[3],
        frames_bad=v[4],
        channels=chans,
        min_frequency_hz=v[13] / 1e3,
        max_frequency_hz=v[14] / 1e3,
        min_pulse_width_s=v[15] / 1e9,
        max_pulse_width_s=v[16] / 1e9,
        max_duty_ratio=v[17] / 1e6,
        watchdog_s=v[18] / 1e3,
        sense_fault=bool(v[1] & FLAG_SENSE_FAULT),
    )


def encode_status(status: ControllerStatus) -> bytes:
    """Inverse of :func:`decode_status` (for tests and host-side fakes)."""
    fields: list[int] = [
        status.version,
        (FLAG_WATCHDOG_TRIPPED if status.watchdog_tripped else 0) | (FLAG_SENSE_FAULT if status.sense_fault else 0),
        _u32(status.uptime_s * 1e3, "uptime_s"),
        status.frames_ok & 0xFFFFFFFF,
        status.frames_bad & 0xFFFFFFFF,
    ]
    for ch in status.channels:
        fields += [
            int(ch.on),
            _u32(ch.frequency_hz * 1e3, "frequency_hz"),
            _u32(ch.pulse_width_s * 1e9, "pulse_width_s"),
            int(round(ch.amplitude * AMPLITUDE_FULL_SCALE)),
        ]
    fields += [
        _u32(status.min_frequency_hz * 1e3, "min_frequency_hz"),
        _u32(status.max_frequency_hz * 1e3, "max_frequency_hz"),
        _u32(status.min_pulse_width_s * 1e9, "min_pulse_width_s"),
        _u32(status.max_pulse_width_s * 1e9, "max_pulse_width_s"),
        _u32(status.max_duty_ratio * 1e6, "max_duty_ratio"),
        int(round(status.watchdog_s * 1e3)),
    ]
    return struct.pack(STATUS_FORMAT, *fields)


# ------------------------------------------------------------ self-sensing and the board's hold

_HOLD_FORMAT = ">BIII"
_PAIR_FORMAT = ">I" + "IIH" * 2
#: SENSE_REPLY payload of a version 2 board: rail [mV] u16, then per channel
#: resistance [uohm] u32, current [uA] u32, bias level u16 (65536 = 1), pulse
#: width [ns] u32, count u16
SENSE_FORMAT_V2 = ">H" + "IIHIH" * 2
#: version 3: the same, then the faulty channels u8 (bit i: channel i)
SENSE_FORMAT = SENSE_FORMAT_V2 + "B"


def encode_hold(channel: int, pulse_energy_j: float, bias_w: float, target_ohm: float) -> bytes:
    """HOLD payload: heat per pulse [J], bias heat [W] and target resistance [ohm]."""
    return struct.pack(
        _HOLD_FORMAT, channel, _u32(pulse_energy_j * 1e9, "pulse_energy_j"), _u32(bias_w * 1e6, "bias_w"),
        _u32(target_ohm * 1e6, "target_ohm"),
    )


def encode_pair(onset_s: float, first: tuple[float, float, float], second: tuple[float, float, float]) -> bytes:
    """PAIR payload: channel 1 starts ``onset_s`` [s] after channel 0; each drive is
    (frequency [Hz], width [s], amplitude)."""
    fields: list[int] = [_u32(onset_s * 1e6, "onset_s")]
    for f, w, a in (first, second):
        fields += [_u32(f * 1e3, "frequency_hz"), _u32(w * 1e9, "pulse_width_s"), int(round(a * AMPLITUDE_FULL_SCALE))]
    return struct.pack(_PAIR_FORMAT, *fields)


@dataclass(frozen=True)
class ChannelSense:
    """One channel's latest self-sensing measurement (SI units; 0 when none yet)."""

    resistance_ohm: float
    current_a: float
    bias_level: float
    pulse_width_s: float
    count: int


@dataclass(frozen=True)
class SenseReport:
    """A SENSE_REPLY: the supply rail [V], each channel's measurement, and which
    channels' sense paths are faulty (None from a version 2 board, which cannot say)."""

    rail_v: float
    channels: tuple[ChannelSense, ...]
    faults: tuple[bool, ...] | None = None


def decode_sense(payload: bytes) -> SenseReport:
    """A :class:`SenseReport` from a SENSE_REPLY payload of either version."""
    v2 = struct.calcsize(SENSE_FORMAT_V2)
    v = struct.unpack(SENSE_FORMAT_V2, payload[:v2]) if len(payload) == v2 else struct.unpack(SENSE_FORMAT, payload)
    chans = tuple(
        ChannelSense(v[1 + 5 * i] / 1e6, v[2 + 5 * i] / 1e6, v[3 + 5 * i] / 65536, v[4 + 5 * i] / 1e9, v[5 + 5 * i])
        for i in range(2)
    )
    faults = None if len(v) == 11 else tuple(bool(v[11] >> i & 1) for i in range(2))
    return SenseReport(v[0] / 1e3, chans, faults)
