# Scheduled pulses on the board (protocol version 4; MicroPython module, copied
# to the board next to main.py; see docs/firmware.md).
#
# The host sends, per channel, the pulses of the next few tens of milliseconds:
# board-clock times [us], widths [us] and event ids.  A frame replaces every
# pulse of its channel not yet fired; a pulse whose id already fired is left out
# (a resent frame never doubles a pulse), and one already past when its frame
# arrives is dropped (a late frame).  The channel (tactile_channel.py) fires each
# one through the running heat estimate, which shortens or skips it.
#
# The board's clock for the host is a 32-bit microsecond count since boot: the
# ticks wrap sooner on MicroPython (2^30 us), so it is carried forward from
# ticks_diff at every pass of the main loop.
#
# MicroPython-compatible code only.

import struct

# channel u8, base time u32 [us, board clock]; then per pulse id u16, offset
# after the base u16 [us], width u16 [us]
EVENTS_HEAD = ">BI"
EVENT_ENTRY = ">HHH"
HEAD_SIZE = 5
ENTRY_SIZE = 6
MAX_EVENTS = 9  # (64 - 5) // 6
# A pulse more than this past when its frame is handled [us] is dropped (counted
# late); less fires at once: the frame's own transit.
LATE_US = 2000
# A frame may reach this far ahead [us]; further is a host error (bad payload).
MAX_AHEAD_US = 1000000
# Two pulses' starts are never closer [us] (the paper's 300 Hz, less 10 %): a
# pulse closer to the one before is skipped.
MIN_GAP_US = 3000
# Ids of fired pulses remembered per channel (a frame holds at most MAX_EVENTS).
FIRED_IDS = 32
# The one-shot timer is armed this early [us] and the last stretch is
# busy-waited, so the pulse starts on its microsecond whatever the timer's grain.
EARLY_US = 500
# counters: fired, shortened (by the heat estimate or the half-gap rule),
# skipped (no room, or too close), late (past when their frame came), repeated
# (an id already fired)
FIRED, SHORTENED, SKIPPED, LATE, REPEATED = 0, 1, 2, 3, 4
PING_FORMAT = ">I"
PONG_FORMAT = ">II" + "HHHHH" * 2


def signed32(x):
    x &= 0xFFFFFFFF
    return x - 0x100000000 if x >= 0x80000000 else x


class BoardClock:
    """The 32-bit microsecond clock the host keeps in step with (see above)."""

    def __init__(self, ticks_us, ticks_diff):
        self.ticks_us = ticks_us
        self.diff = ticks_diff
        self.at = ticks_us()
        self.us = 0

    def now(self, ticks=None):
        """The clock [us, mod 2^32] at ``ticks`` (now by default); carries it forward."""
        t = self.ticks_us() if ticks is None else ticks
        d = self.diff(t, self.at)
        if d > 0:
            self.us = (self.us + d) & 0xFFFFFFFF
            self.at = t
        return self.us


def pong(payload, clock_us, queues):
    """PONG's payload for a PING's (None: a bad one): the host's token echoed, the
    board's clock now [us] (the host keeps it in step), and each channel's
    counters of scheduled pulses (two channels; a missing one counts zeros)."""
    if len(payload) != 4:
        return None
    fields = [struct.unpack(PING_FORMAT, payload)[0], clock_us]
    for i in range(2):
        fields += queues[i].counts if i < len(queues) else [0, 0, 0, 0, 0]
    return struct.pack(PONG_FORMAT, *fields)


def parse(payload, channels, min_us, max_us):
    """(channel, base [us], [(id, offset [us], width [us])]) of an EVENTS payload,
    or an int: 1 bad payload, 2 width outside min_us .. max_us, 3 channel."""
    n = len(payload) - HEAD_SIZE
    if n < 0 or n % ENTRY_SIZE or n // ENTRY_SIZE > MAX_EVENTS:
        return 1
    index, base = struct.unpack(EVENTS_HEAD, payload[:HEAD_SIZE])
    if index >= channels:
        return 3
    out = []
    last = 0
    for k in range(n // ENTRY_SIZE):
        i = HEAD_SIZE + k * ENTRY_SIZE
        eid, off, w = struct.unpack(EVENT_ENTRY, payload[i:i + ENTRY_SIZE])
        if off < last:
            return 1
        if w < min_us or w > max_us:
            return 2
        last = off
        out.append((eid, off, w))
    return index, base, out


class EventQueue:
    """One channel's scheduled pulses: (due [ticks], id, width [us]) in order,
    the ids already fired, and the counters."""

    def __init__(self):
        self.pending = []
        self.fired = []
        self.counts = [0, 0, 0, 0, 0]

    def count(self, which):
        self.counts[which] = (self.counts[which] + 1) & 0xFFFF

    def replace(self, now, rel_entries, ticks_add):
        """The channel's new schedule: ``rel_entries`` as (id, start after ``now``
        [us], width [us]).  Replaces every pulse not yet fired.  A start more
        than LATE_US past is dropped before any tick arithmetic: ticks_add
        refuses intervals of 2^29 us or more."""
        pending = []
        for eid, rel, w in rel_entries:
            if eid in self.fired:
                self.count(REPEATED)
                continue
            if rel < -LATE_US:
                self.count(LATE)
                continue
            pending.append((ticks_add(now, rel), eid, w))
        self.pending = pending

    def pop(self):
        """The next pulse, remembered as fired whatever the gate makes of it."""
        p = self.pending.pop(0)
        self.fired.append(p[1])
        if len(self.fired) > FIRED_IDS:
            self.fired.pop(0)
        return p

    def clear(self):
        self.pending = []
