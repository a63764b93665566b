"""Waiting on a state, never on a clock: the one helper the tests poll with."""

from __future__ import annotations

import time


def wait_for(predicate, timeout_s: float = 10.0) -> bool:
    """Poll ``predicate`` every 10 ms until it holds or ``timeout_s`` [s] pass (a bound for a
    loaded machine, not an assertion on time); returns its last answer."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return predicate()
