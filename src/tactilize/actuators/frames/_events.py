"""The payloads of protocol version 4: scheduled pulses (EVENTS) and the board's clock (PING/PONG).

EVENTS carries one channel's pulses of the next few tens of milliseconds::

    channel u8 | base u32 [us, board clock] | n x (id u16, offset u16 [us after base], width u16 [us])

with at most :data:`MAX_EVENTS` pulses, offsets not decreasing, widths within the
controller's hard limits.  The board replaces every pulse of the channel not yet
fired with these, leaves out an id it already fired (a resent frame never doubles
a pulse) and drops a pulse already past by more than 2 ms when the frame
arrives (a late frame); each one then passes its running heat estimate, which
shortens or skips it (``tactilize/firmware/tactile_events.py``).

PING carries a host token u32; PONG echoes it with the board's clock u32 [us,
since boot, mod 2**32] read when the PING was handled, and per channel the
counters of scheduled pulses (u16 each, wrapping): fired, shortened, skipped,
late, repeated.

Units: the board's microseconds on the wire; SI in the decoded values.
"""

from __future__ import annotations

import struct
from typing import NamedTuple, Sequence

__all__ = [
    "MAX_EVENTS", "EventCounts", "Pong", "encode_events", "decode_events", "encode_ping", "decode_pong",
    "encode_pong",
]

_HEAD = ">BI"
_ENTRY = ">HHH"
#: most pulses in one EVENTS frame: (64 - 5) // 6
MAX_EVENTS = 9
#: largest offset after the base [us]
MAX_OFFSET_US = 0xFFFF
_PONG = ">II" + "HHHHH" * 2


class EventCounts(NamedTuple):
    """One channel's scheduled pulses so far, as the board counts them (each mod 2**16)."""

    fired: int
    shortened: int
    skipped: int
    late: int
    repeated: int


class Pong(NamedTuple):
    """A PONG: the host's token, the board's clock [us, mod 2**32], the counters per channel."""

    token: int
    board_us: int
    counts: tuple[EventCounts, ...]


def encode_events(channel: int, base_us: int, pulses: Sequence[tuple[int, int, int]]) -> bytes:
    """EVENTS payload: ``pulses`` as (id, offset after ``base_us`` [us], width [us]).

    ``base_us`` is taken mod 2**32 (the board's clock wraps there)."""
    if len(pulses) > MAX_EVENTS:
        raise ValueError(f"{len(pulses)} pulses exceed {MAX_EVENTS} per frame")
    out = [struct.pack(_HEAD, channel, int(base_us) & 0xFFFFFFFF)]
    last = 0
    for eid, off, width in pulses:
        if not 0 <= off <= MAX_OFFSET_US or off < last:
            raise ValueError(f"offset {off} us out of order or beyond {MAX_OFFSET_US}")
        last = off
        out.append(struct.pack(_ENTRY, eid & 0xFFFF, off, width))
    return b"".join(out)


def decode_events(payload: bytes) -> tuple[int, int, list[tuple[int, int, int]]]:
    """Inverse of :func:`encode_events`: (channel, base [us], [(id, offset [us], width [us])])."""
    n = len(payload) - 5
    if n < 0 or n % 6:
        raise ValueError(f"an EVENTS payload of {len(payload)} bytes")
    channel, base = struct.unpack(_HEAD, payload[:5])
    return channel, base, [struct.unpack(_ENTRY, payload[5 + 6 * k : 11 + 6 * k]) for k in range(n // 6)]


def encode_ping(token: int) -> bytes:
    """PING payload: a host token u32 the PONG echoes."""
    return struct.pack(">I", token & 0xFFFFFFFF)


def decode_pong(payload: bytes) -> Pong:
    v = struct.unpack(_PONG, payload)
    return Pong(v[0], v[1], (EventCounts(*v[2:7]), EventCounts(*v[7:12])))


def encode_pong(pong: Pong) -> bytes:
    """Inverse of :func:`decode_pong` (for tests and host-side fakes)."""
    fields = [pong.token, pong.board_us]
    for c in pong.counts:
        fields += list(c)
    return struct.pack(_PONG, *fields)
