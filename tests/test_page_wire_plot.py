"""The page's plot of the simulated wire (static/plot.js) in headless Chromium.

Wire messages carry samples on the simulation's clock and arrive with varying
delay.  Each was aligned so that its newest sample was "now", so a message that came
late was drawn stretched back over the one before: the trace ran backwards in time in
places (seen on the page).  Now the plot maps the simulation's clock by the least lag:
the trace must only go forward, keep its samples' spacing, and stay near "now".
"""

from __future__ import annotations

import pytest

from test_browser import browser, opened_page, server  # noqa: F401  (fixtures)

# Messages of 20 ms of samples (1 ms apart) every 20 ms of page time, each late by a random
# 0 .. 12 ms; performance.now is the test's clock.
_SCRIPT = """async (seed) => {
  const { Plot } = await import('/static/plot.js');
  let t = 100.0;
  const realNow = performance.now.bind(performance);
  performance.now = () => t * 1e3;
  const plot = new Plot(document.createElement('canvas'), 2);
  plot.running = false;
  let x = seed;
  const rnd = () => { x = (x * 1103515245 + 12345) % 2147483648; return x / 2147483648; };
  const lateness = [];
  for (let k = 0; k < 200; k++) {
    const sim = Array.from({ length: 20 }, (_, i) => 5.0 + 0.020 * k + 0.001 * (i + 1));
    const late = 0.012 * rnd();
    lateness.push(late);
    t = 100.0 + 0.020 * (k + 1) + late;
    plot.addWire(sim, [sim.map(() => 1.0), sim.map(() => 2.0)], ['vibrating', 'vibrating']);
  }
  performance.now = realNow;
  return { times: plot.wire.map((p) => p[0]), now: t, late: lateness };
}"""


@pytest.mark.parametrize("seed", [1, 7, 42])
def test_the_wire_trace_only_goes_forward_and_keeps_its_spacing(browser, server, seed):  # noqa: F811
    with opened_page(browser, server) as page:
        got = page.evaluate(_SCRIPT, seed)
    times = got["times"]
    assert len(times) > 300  # 0.5 s of 1 ms samples, less what fell out of the window
    steps = [b - a for a, b in zip(times, times[1:])]
    assert min(steps) > 0  # before: backward steps wherever a message came later than the one before
    # Within a message samples stay 1 ms apart; between messages the gap moves by at most the
    # catch-up allowance (2 ms), where re-aligning to "now" moved it by the lateness (up to 12 ms).
    assert max(abs(s - 0.001) for s in steps) <= 0.0021
    # The newest sample is drawn no later than "now" and no more than the largest lateness before it.
    assert got["now"] - max(got["late"]) - 0.0021 <= times[-1] <= got["now"] + 1e-9
