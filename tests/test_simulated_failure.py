"""If the simulated wire's thread ever stops on an error, the output goes safe
and says so: before, a drive the schedule could not place (600 kHz) killed the
thread and the page kept saying "vibrating" while the model was frozen."""

from __future__ import annotations


import pytest

from tactilize.actuators.simulated import SimulatedOutput
from tactilize.drive import Drive
from tactilize.errors import OutputError
from _waiting import wait_for



def test_a_dead_simulation_thread_turns_the_output_safe_and_says_so():
    out = SimulatedOutput(tick_s=0.005)
    try:
        assert out.connected and out.fault is None
        out.apply([Drive(600_000.0, 1e-6), Drive(100.0, 3e-4)])
        assert wait_for(lambda: not out.connected, 30.0), "the thread never stopped (or never said so)"
        assert "SignalError" in out.fault and "output is off" in out.fault
        assert [s["state"] for s in out.state()] == ["failed", "failed"]
        assert all(c.state == "off" for c in out.controllers)
        assert all(s["drive"]["pulse_frequency_hz"] == 0 for s in out.state())
        with pytest.raises(OutputError, match="simulated wire stopped"):
            out.apply([Drive(100.0, 3e-4), Drive.off()])
    finally:
        out.close()


def test_a_running_simulation_is_connected_without_a_fault():
    out = SimulatedOutput(start=False)
    out.apply([Drive(100.0, 3e-4), Drive.off()])
    out.advance(0.05)
    assert out.connected and out.fault is None and out.state()[0]["state"] != "failed"
    out.close()


def test_the_pages_wire_legend_says_failed_once_the_thread_stopped():
    from tactilize.web.session import _wire_source

    out = SimulatedOutput(tick_s=0.005)
    try:
        pull = _wire_source(out)
        out.apply([Drive(600_000.0, 1e-6), Drive.off()])
        assert wait_for(lambda: not out.connected, 30.0)
        msg = pull()
        assert msg is not None and msg["state"] == ["failed", "failed"]
    finally:
        out.close()
