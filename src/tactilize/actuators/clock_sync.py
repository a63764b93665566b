"""The board's clock, kept in step from the host: offset and drift from timestamp exchanges.

Each exchange is a PING sent at host time ``t0``, answered by a PONG carrying the
board's clock ``b`` (read when the board handled the PING) and received at ``t1``.
The board read its clock somewhere in ``[t0, t1]``; taking the midpoint, the error
is at most half the round trip, and most of a long round trip is queueing on one
side, not the other.  So, as NTP and Cristian's method do (docs/references.md,
section 8 (clock sync)), the exchanges with the shortest round trips are trusted:
of every :data:`BLOCK` consecutive exchanges the one with the least round trip is
kept (unless even it is far above the others, :data:`CLEAN_RTT_FACTOR`),
and a straight line ``b = offset + rate * t`` is fitted to the kept points of
the last :data:`WINDOW` exchanges by least squares.  Its residual (the RMS distance
of the kept points from the line) says how well the host knows the board's clock.

Units: host times in seconds (``time.monotonic``), board times in microseconds.
The board's clock is 32 bits wide and wraps (every 71.6 minutes); this class
unwraps it.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

__all__ = ["ClockSync", "BLOCK", "WINDOW"]

#: Exchanges per block; the one with the least round trip is kept.
BLOCK = 4
#: Exchanges remembered for the fit (at the host's 50 ms heartbeat: 3.2 s).
WINDOW = 64
#: A kept exchange's round trip may be at most this many times the least one, or
#: the median of the blocks' least ones, whichever is more.
CLEAN_RTT_FACTOR = 2.0
#: The kept exchanges must span this long [s] before a drift is fitted.
MIN_SPAN_S = 1.0
_WRAP = 1 << 32


class ClockSync:
    """Offset and drift of the board's microsecond clock against the host's seconds."""

    def __init__(self, block: int = BLOCK, window: int = WINDOW) -> None:
        self.block = int(block)
        self._raw: deque[tuple[float, float, float]] = deque(maxlen=int(window))  # (mid [s], board [us], rtt [s])
        self._last_board: int | None = None
        self._wraps = 0
        self._fit: tuple[float, float, float] | None = None  # (t_ref [s], board at t_ref [us], rate [us/s])
        #: RMS distance of the kept exchanges from the fitted line [us]; None before two are kept
        self.residual_us: float | None = None
        #: the least round trip among the remembered exchanges [us]
        self.rtt_us: float | None = None
        #: exchanges taken
        self.count = 0

    @property
    def ready(self) -> bool:
        """At least one exchange: board times can be predicted."""
        return self._fit is not None

    @property
    def drift_ppm(self) -> float:
        """How much faster the board's clock runs than the host's [parts per million]."""
        return 0.0 if self._fit is None else (self._fit[2] / 1e6 - 1.0) * 1e6

    def add(self, sent_s: float, board_us: int, received_s: float) -> None:
        """One exchange: PING sent at ``sent_s`` [s], the board's clock ``board_us``
        [us, mod 2**32], PONG received at ``received_s`` [s]."""
        board = int(board_us) % _WRAP
        if self._last_board is not None and board < self._last_board - _WRAP // 2:
            self._wraps += 1
        self._last_board = board
        rtt = max(0.0, received_s - sent_s)
        self._raw.append((0.5 * (sent_s + received_s), float(board + self._wraps * _WRAP), rtt))
        self.count += 1
        self._refit()

    def _refit(self) -> None:
        raw = list(self._raw)
        self.rtt_us = min(r for _, _, r in raw) * 1e6
        kept = [min(raw[i : i + self.block], key=lambda e: e[2]) for i in range(0, len(raw), self.block)]
        # A block whose every exchange was held up is left out too: above twice
        # the least round trip and above the median block's.
        low = min(r for _, _, r in raw)
        typical = float(np.median([k[2] for k in kept]))
        clean = [k for k in kept if k[2] <= max(CLEAN_RTT_FACTOR * low, typical)]
        kept = clean if len(clean) >= 2 else kept
        t = np.array([k[0] for k in kept])
        b = np.array([k[1] for k in kept])
        t_ref = float(t[-1])
        x = t - t_ref
        if len(kept) < 2 or np.ptp(t) < MIN_SPAN_S:
            # Too short a span to tell a drift from the round trips' own spread:
            # the offset alone (the median of the kept points), at the last rate.
            rate = 1e6 if self._fit is None else self._fit[2]
            at_ref = float(np.median(b - rate * x))
        else:
            rate, at_ref = np.polyfit(x, b - b[-1], 1)
            at_ref += b[-1]
        self._fit = (t_ref, float(at_ref), float(rate))
        res = b - (at_ref + rate * x)
        self.residual_us = float(math.sqrt(float(np.mean(res**2)))) if len(kept) >= 2 else None

    def board_us(self, host_s: float) -> float:
        """The board's clock [us, unwrapped] at host time ``host_s`` [s]."""
        if self._fit is None:
            raise RuntimeError("no clock exchange yet")
        t_ref, at_ref, rate = self._fit
        return at_ref + rate * (host_s - t_ref)

    def host_s(self, board_us: float) -> float:
        """The host time [s] at the board's clock ``board_us`` [us, unwrapped]."""
        if self._fit is None:
            raise RuntimeError("no clock exchange yet")
        t_ref, at_ref, rate = self._fit
        return t_ref + (board_us - at_ref) / rate
