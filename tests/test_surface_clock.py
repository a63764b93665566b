"""The stroke clock's least lag (surface/clock.py): the windowed queue gives exactly what a
pass over every lag of the window gives, and a batch's work does not grow with the window."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from tactilize.surface.clock import LAG_RESET_S, LAG_WINDOW_S, StrokeClock


class _Reference:
    """The rule written plainly: every lag of the window kept, the least found by a pass."""

    def __init__(self) -> None:
        self.lags: list[tuple[float, float]] = []

    def host_s(self, now_s: float, host_now_s: float) -> float:
        lag = host_now_s - now_s
        lags = [(h, g) for h, g in self.lags if h >= host_now_s - LAG_WINDOW_S]
        if lags:
            least = min(g for _, g in lags)
            if lag > least + LAG_RESET_S or lag < least - LAG_RESET_S:
                lags = []
        lags.append((host_now_s, lag))
        self.lags = lags
        return min(g for _, g in lags)


_step = st.tuples(
    st.floats(0.0, 0.3, allow_nan=False),  # stroke time advance [s]
    st.floats(0.0, 0.8, allow_nan=False),  # host time advance [s]
)


@settings(max_examples=300, deadline=None)
@given(st.lists(_step, min_size=1, max_size=80), st.floats(-5.0, 5.0, allow_nan=False))
def test_least_lag_equals_a_pass_over_the_window(steps, host0):
    clock, ref = StrokeClock(), _Reference()
    now, host = 0.0, host0
    for d_now, d_host in steps:
        now += d_now
        host += d_host
        assert clock.host_s(now, host) == ref.host_s(now, host)
        assert clock.played_until_s(now, host) == host - ref.host_s(now, host)


def test_steady_batches_keep_few_lags():
    # 4 ms batches for the whole window, on time or with the page's clock running a little
    # fast: a pass over the window walked all 500 of its lags every batch.
    clock = StrokeClock()
    for k in range(2000):
        clock.host_s(4e-3 * k, 100.0 + 4e-3 * k)
    assert len(clock._lags) == 1
    for k in range(2000, 4000):
        clock.host_s(4e-3 * k, 100.0 + 4e-3 * k - 1e-7 * k)
    assert len(clock._lags) == 1
