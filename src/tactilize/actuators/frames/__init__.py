"""The serial byte format between the host and the tactile controller.

Pure functions and plain data, no I/O and no pyserial: the host's
:class:`~tactilize.actuators.serial.SerialOutput` uses it, tests fuzz it, and the
firmware (``tactilize/firmware/``) speaks the same bytes.  The frame layer
(start byte, length, sequence, command, CRC) is :mod:`._framing`; the payloads
up to version 3 :mod:`._payloads`, those of version 4 :mod:`._events`.

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
PING      0x08  (version 4) a host token u32: the controller answers with a PONG.
EVENTS    0x09  (version 4) one channel's scheduled pulses: board-clock times,
                widths and ids (:mod:`._events`); replaces those not yet fired.
========  ====  ==========================================================

Replies, controller to host (``SEQ`` echoes the sequence number of the frame
they answer, so the host can match replies to requests):

============  ====  ====================================================
ACK           0x80  command u8 (the command acknowledged), flags u8 (see
                    :data:`FLAG_WATCHDOG_TRIPPED`, :data:`FLAG_SENSE_FAULT`)
NAK           0x81  reason u8, detail u8 (see :class:`NakReason`, :class:`Refused`)
STATUS_REPLY  0x82  see :data:`STATUS_FORMAT` and :class:`ControllerStatus`
SENSE_REPLY   0x83  see :data:`SENSE_FORMAT` and :class:`SenseReport`
PONG          0x84  (version 4) see :class:`Pong`: the board's clock and counters
============  ====  ====================================================

Every command is idempotent, so the host may resend a frame whose ACK got lost:
a SET (or PAIR) equal to the one running changes nothing on the board, and an
EVENTS frame resent leaves out the pulses whose ids already fired.

Versions (STATUS_REPLY's first byte): 2, and 3, which adds the sense-fault flag
(bit 1 of the ACK and STATUS flags) and, when a SENSE carries the host's version
(:data:`SENSE_V3`), one byte after SENSE_REPLY's fields, bit ``i`` set when
channel ``i``'s sense path is faulty; an empty SENSE gets the version 2 reply, so
older hosts keep working with newer boards.  The host learns the board's version
from the STATUS reply of its handshake and asks with its version only then;
:func:`decode_sense` reads both lengths (``faults`` is None for version 2).
Version 4 adds PING/PONG and EVENTS; a version 3 board answers them with NAK
"unknown command", and its host drives it with SETs as before.
Wire units are integers (millihertz, nanoseconds) because the firmware works in
integers; :func:`encode_set_channel` converts from SI.

The firmware carries its own minimal copy of the codec (MicroPython lacks
``dataclasses`` and ``enum``); the tests run this package against that copy over a
pseudo-terminal so they cannot drift apart.
"""

from __future__ import annotations

from ._events import (
    MAX_EVENTS, EventCounts, Pong, decode_events, decode_pong, encode_events, encode_ping, encode_pong,
)
from ._framing import (
    FLAG_FIRMWARE_ERROR, FLAG_SENSE_FAULT, FLAG_WATCHDOG_TRIPPED, HEADER_SIZE, MAX_PAYLOAD, OVERHEAD, PROTOCOL_VERSION, SENSE_V3, START,
    Command, Frame, FrameDecoder, NakReason, Refused, command_name, crc16_ccitt, decode_nak, encode_frame,
)
from ._payloads import (
    AMPLITUDE_FULL_SCALE, REGULARITY_EVEN, SENSE_FORMAT, SENSE_FORMAT_V2, STATUS_FORMAT, ChannelSense,
    ChannelStatus, ControllerStatus, SenseReport, SetChannel, decode_sense, decode_set_channel, decode_status,
    encode_hold, encode_pair, encode_set_channel, encode_status,
)

__all__ = [
    "command_name", "START", "MAX_PAYLOAD", "HEADER_SIZE", "OVERHEAD", "Command", "NakReason", "Refused", "Frame",
    "FrameDecoder", "crc16_ccitt", "encode_frame", "encode_set_channel", "decode_set_channel", "SetChannel",
    "ControllerStatus", "ChannelStatus", "decode_status", "encode_status", "decode_nak", "STATUS_FORMAT",
    "SENSE_FORMAT", "SENSE_FORMAT_V2", "encode_hold", "encode_pair", "ChannelSense", "SenseReport", "decode_sense",
    "AMPLITUDE_FULL_SCALE", "REGULARITY_EVEN", "FLAG_WATCHDOG_TRIPPED", "FLAG_SENSE_FAULT", "FLAG_FIRMWARE_ERROR", "PROTOCOL_VERSION",
    "SENSE_V3", "MAX_EVENTS", "EventCounts", "Pong", "encode_events", "decode_events", "encode_ping", "decode_pong",
    "encode_pong",
]
