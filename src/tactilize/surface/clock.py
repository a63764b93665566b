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

Units: seconds.
"""

from __future__ import annotations

__all__ = ["StrokeClock", "LAG_WINDOW_S", "LAG_RESET_S"]

#: How long the least lag between the stroke's clock and the host's is remembered [s].
LAG_WINDOW_S = 2.0
#: A lag this far above (or below) the least one is a new clock (another page, a new stroke) [s].
LAG_RESET_S = 0.5


class StrokeClock:
    """Host time = stroke time + the least lag seen lately (see the module's docstring)."""

    def __init__(self) -> None:
        self._lags: list[tuple[float, float]] = []  # (host time [s], lag [s])

    def host_s(self, now_s: float, host_now_s: float) -> float:
        """The host time [s] of stroke time 0, given that ``now_s`` [s] is now (``host_now_s`` [s])."""
        lag = host_now_s - now_s
        lags = [(h, g) for h, g in self._lags if h >= host_now_s - LAG_WINDOW_S]
        if lags and (lag > min(g for _, g in lags) + LAG_RESET_S or lag < min(g for _, g in lags) - LAG_RESET_S):
            lags = []
        lags.append((host_now_s, lag))
        self._lags = lags
        return min(g for _, g in lags)

    def played_until_s(self, now_s: float, host_now_s: float) -> float:
        """The stroke time [s] an output following this clock has reached when stroke time
        ``now_s`` arrives at ``host_now_s``: ``now_s`` plus how late this batch is."""
        return host_now_s - self.host_s(now_s, host_now_s)
