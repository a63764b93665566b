"""The stroke's clock on the host's: one rule for every place that maps the two.

The page stamps its samples on its own clock; the host receives them some time
later.  Each batch says "stroke time ``now_s`` is now", but a batch can come late
(held up on the way, a busy thread), and mapping each batch's events from its own
arrival would move every pulse by that delay, and move a pulse sent again from one
batch to the next.  The least lag over :data:`LAG_WINDOW_S` is the batch that came
quickest: the mapping follows it, steady from batch to batch.  A lag far from it
(:data:`LAG_RESET_S`) is a new clock and starts afresh.

Used by the outputs that schedule events on their own clock (the serial board) and
by the pen's renderer, which needs to know which pulses an output has played by now
(a late batch must not re-schedule a bump the output already played).

The least lag over the window is kept as a queue of the lags that can still become
the least (each newer and smaller than the one before it): a batch costs a few
steps however many batches the window holds (500 at 4 ms batches), not a pass over
them all.

Units: seconds.
"""

from __future__ import annotations

from collections import deque

__all__ = ["StrokeClock", "LAG_WINDOW_S", "LAG_RESET_S"]

#: How long the least lag between the stroke's clock and the host's is remembered [s].
LAG_WINDOW_S = 2.0
#: A lag this far above (or below) the least one is a new clock (another page, a new stroke) [s].
LAG_RESET_S = 0.5


class StrokeClock:
    """Host time = stroke time + the least lag seen lately (see the module's docstring)."""

    def __init__(self) -> None:
        # (host time [s], lag [s]) of the lags that may yet be the least: host times and
        # lags both increase along it, so the least of the window is its first.
        self._lags: deque[tuple[float, float]] = deque()

    def host_s(self, now_s: float, host_now_s: float) -> float:
        """The host time [s] of stroke time 0, given that ``now_s`` [s] is now (``host_now_s`` [s],
        never earlier than the previous call's: a monotonic clock)."""
        lag = host_now_s - now_s
        lags = self._lags
        oldest = host_now_s - LAG_WINDOW_S
        while lags and lags[0][0] < oldest:
            lags.popleft()
        if lags and (lag > lags[0][1] + LAG_RESET_S or lag < lags[0][1] - LAG_RESET_S):
            lags.clear()
        # A lag no smaller than this one, seen before it, can never be the least again.
        while lags and lags[-1][1] >= lag:
            lags.pop()
        lags.append((host_now_s, lag))
        return lags[0][1]

    def played_until_s(self, now_s: float, host_now_s: float) -> float:
        """The stroke time [s] an output following this clock has reached when stroke time
        ``now_s`` arrives at ``host_now_s``: ``now_s`` plus how late this batch is."""
        return host_now_s - self.host_s(now_s, host_now_s)
