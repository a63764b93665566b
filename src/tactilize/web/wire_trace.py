"""The simulated wire's trace for the pen page's plot: what is new since the last message."""

from __future__ import annotations

import math
from typing import Any

from ..encode import dumps

__all__ = ["trace_text", "wire_source", "WIRE_PERIOD_S"]

#: Period of the wire trace messages [s].
WIRE_PERIOD_S = 0.05


def trace_text(source: Any) -> str | None:
    trace = source()
    return None if trace is None else dumps(trace, compact=True)


def wire_source(output: Any):
    """A callable returning the newest wire trace message, or None when the
    output keeps no trace (serial, audio).

    The simulated output's ``traces(seconds)`` gives ``time_s`` and, per channel,
    ``displacement_um``; this sends what is new since the previous call,
    thinned to about 1 kHz (the wire is a low-pass filter; the page's plot is
    720 px wide for 0.5 s).
    """
    if output.traces(0.0) is None:
        return None
    fn = output.traces
    last_t = [-math.inf]
    span_s = 2 * WIRE_PERIOD_S

    def pull() -> dict[str, Any] | None:
        tr = fn(span_s)
        t = tr.get("time_s") or []
        chans = tr.get("channels") or []
        if getattr(output, "fault", None) and not getattr(output, "connected", True):
            # A stopped simulation makes no new points: its legend must not keep its last state.
            return {"type": "wire", "t_s": [], "displacement_um": [[] for _ in chans], "state": ["failed"] * len(chans)}
        if not t or not chans:
            return None
        first = 0
        while first < len(t) and t[first] <= last_t[0]:
            first += 1
        if first >= len(t):
            return None
        last_t[0] = t[-1]
        rate = (len(t) - 1) / (t[-1] - t[0]) if t[-1] > t[0] else 1000.0
        step = max(1, int(rate // 1000))
        idx = range(first, len(t), step)
        return {
            "type": "wire",
            "t_s": [t[i] for i in idx],
            "displacement_um": [[c["displacement_um"][i] for i in idx] for c in chans],
            # Each wire's controller state at the newest point (the page's legend).
            "state": [(c.get("state") or ["off"])[-1] for c in chans],
        }

    return pull
