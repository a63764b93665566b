"""The simulated output: envelope in apply, real-time thread, traces for the page."""

from __future__ import annotations

import time

import numpy as np
import pytest

from tactilize.actuators.base import Output
from tactilize.actuators.sma import WireSpec, build_envelope
from tactilize.actuators.simulated import SimulatedOutput
from tactilize.mapping import Drive

SPEC = WireSpec.preset("75um")


@pytest.fixture(scope="module")
def envelope():
    return build_envelope(SPEC)


def rising_edges(x) -> int:
    on = np.asarray(x) > 0
    return int(np.count_nonzero(on[1:] & ~on[:-1]))


def test_apply_passes_every_drive_through_the_controller_and_the_envelope(envelope):
    with SimulatedOutput(SPEC, envelope=envelope, start=False) as out:
        assert isinstance(out, Output)
        hot = Drive(50.0, 3e-3)  # 15 % duty, no strength: placed in the band by its heat
        applied = out.apply([hot, Drive(50.0, 1e-3, 1.0, (), 0.5)])
        assert "band" in applied[0].clamped
        ctrl = out.controllers[0]
        lo, hi = ctrl.band_j(50.0)
        power = out.circuit.power_at(SPEC.resistance_martensite_ohm)
        assert applied[0].pulse_width_s * power == pytest.approx(hi, rel=0.02)
        assert lo * 0.98 <= applied[1].pulse_width_s * power <= hi * 1.02
        assert applied[0].pulse_width_s * power <= envelope.max_pulse_energy_j(50.0)
        # a shorter list turns the other channel off
        assert out.apply([Drive(50.0, 1e-3)])[1].is_off


def test_simulated_wire_follows_and_traces_show_it(envelope):
    d = Drive(50.0, 1e-3, 1.0, (), 0.5)
    with SimulatedOutput(SPEC, envelope=envelope, start=False, trace_seconds=2.0, trace_rate_hz=2000) as out:
        out.apply([d, Drive.off()])
        for _ in range(350):  # 7 s in 20 ms ticks, as the thread would
            out.advance(0.02)
        assert out.time_s == pytest.approx(7.0)
        tr = out.traces(1.0)
        t = np.array(tr["time_s"])
        assert t.size == 2000 and np.all(np.diff(t) > 0) and t[-1] == pytest.approx(7.0)
        ch0, ch1 = tr["channels"]
        # 50 pulses in the last second, each marked near the circuit's current
        cur = np.array(ch0["current_a"])
        pulses = cur > 0.3
        assert rising_edges(pulses) + int(pulses[0]) == 50
        assert cur.max() == pytest.approx(out.circuit.current_at(SPEC.resistance_at(0.8)), rel=0.03)
        # between pulses the standby bias is a small chopped current
        assert 0 < np.median(cur[~pulses]) < 0.05
        disp = np.array(ch0["displacement_um"])
        rises = np.diff(disp)
        assert disp.max() - disp.min() > 0.5
        peaks = np.flatnonzero((rises[:-1] > 0) & (rises[1:] <= 0))
        assert 45 <= peaks.size <= 55
        assert SPEC.martensite_finish_c < np.mean(ch0["temperature_c"]) < SPEC.austenite_finish_c
        assert set(ch0["state"]) == {"vibrating"}
        # every pulse of the last second has its own peak of at least 0.5 um
        log = [p for p in out.pulse_log(0) if p[0] > 6.0]
        assert len(log) >= 45 and all(rise >= 0.5e-6 for _, rise, _ in log)
        # the idle channel was never driven: it stays off, at ambient and still
        assert max(ch1["current_a"]) == 0 and np.ptp(ch1["displacement_um"]) == 0
        assert ch1["temperature_c"][-1] == pytest.approx(SPEC.ambient_c)
        assert set(ch1["state"]) == {"off"}


def test_reapplying_the_same_drive_keeps_the_phase(envelope):
    d = Drive(100.0, 0.5e-3, 1.0, (), 0.5)
    with SimulatedOutput(SPEC, envelope=envelope, start=False, trace_seconds=1.0, trace_rate_hz=5000) as out:
        out.apply([d, d])
        for _ in range(60):  # the page re-sends the drive every frame
            out.advance(1 / 60)
            out.apply([d, d])
        tr = out.traces(0.9)
        cur = np.array(tr["channels"][0]["current_a"]) > 0.3
        t = np.array(tr["time_s"])
        onsets = t[1:][cur[1:] & ~cur[:-1]]
        # one pulse every 10 ms, never restarted by the repeated apply
        assert onsets.size >= 88
        assert np.allclose(np.diff(onsets), 0.01, atol=0.2e-3)


def test_stop_turns_everything_off_and_the_wire_cools(envelope):
    with SimulatedOutput(SPEC, envelope=envelope, start=False) as out:
        out.apply([Drive(50.0, 1e-3), Drive(50.0, 1e-3)])
        for _ in range(100):
            out.advance(0.02)
        warm = out.state()[0]["temperature_c"]
        out.stop()
        for _ in range(150):
            out.advance(0.02)
        st = out.state()
        assert all(s["drive"]["pulse_frequency_hz"] == 0 for s in st)
        assert max(out.traces(2.0)["channels"][0]["current_a"][-2000:]) == 0
        assert all(s["state"] == "off" for s in st)
        # 3 s of cooling with tau ~ 0.53 s: within a few per cent of ambient rise
        rise = st[0]["temperature_c"] - SPEC.ambient_c
        assert rise < 0.05 * (warm - SPEC.ambient_c)


def _wait_for(predicate, timeout_s: float = 30.0) -> bool:
    deadline = time.monotonic() + timeout_s  # a bound only: a loaded machine is slow
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.01)
    return predicate()


def test_real_time_thread_runs_and_close_joins(envelope):
    # The thread follows its clock (injected: 10 ms a reading), not the host's pace.
    now = [100.0]

    def clock():
        now[0] += 0.010
        return now[0]

    out = SimulatedOutput(SPEC, envelope=envelope, tick_s=0.01, clock=clock)
    out.apply([Drive(200.0, 0.2e-3), Drive(200.0, 0.2e-3)])
    assert _wait_for(lambda: out.time_s > 0.3)
    # never ahead of its clock (the first reading is its start)
    assert out.time_s <= now[0] - 100.010 + 1e-9
    thread = out._thread
    out.close()
    assert thread is not None and not thread.is_alive()
    assert out.state()[0]["drive"]["pulse_frequency_hz"] == 0


def test_the_real_time_thread_advances_in_slices_so_a_pen_batch_never_waits_a_tick(envelope):
    # A clock that jumps 23 ms between readings: every tick has 23 ms to simulate.
    now = [100.0]

    def clock():
        now[0] += 0.023
        return now[0]

    out = SimulatedOutput(SPEC, envelope=envelope, tick_s=0.005, start=False, clock=clock)
    steps: list[float] = []
    advance = out.advance
    out.advance = lambda d: (steps.append(d), advance(d))[1]
    out.start()
    assert _wait_for(lambda: len(steps) >= 8)
    out.close()
    # Each hold of the lock covers at most 5 ms of simulated time; the slices of a
    # tick add up to the tick (23 ms: 5 + 5 + 5 + 5 + 3).
    assert max(steps) <= 0.005 + 1e-12
    assert steps[:5] == pytest.approx([0.005, 0.005, 0.005, 0.005, 0.003])
    assert out.time_s == pytest.approx(sum(steps), abs=1e-6)
