"""The hardware limits of docs/hardware.md ("Defence in depth") hold the wire under its maximum
with the gate's logic stuck high or toggled by a runaway, judged on the host's wire model."""

from __future__ import annotations

import math

import pytest

from tactilize.actuators.sma import Circuit, WireSpec
from tactilize.actuators.sma.limiter import AcCoupledGate, HardwareLimit, preset_limit
from tactilize.actuators.sma.limiter_worst import judge_limit, peak_c, runaway_sweep, stuck_high_peak_c, worst_runaway

WIRE = WireSpec()
MAX_C = WIRE.max_temperature_c
#: The presets docs/hardware.md calls safe in the design air (30 C).
SAFE_PRESETS = ("aa-resistor", "usb-resistor", "aa-sink")


def test_the_ac_coupled_gate_conducts_for_r_c_ln_of_drive_over_threshold():
    # 100 kOhm x 68 nF = 6.8 ms; ln(3.3 / 0.65) = 1.6247, worked by hand: 11.048 ms.
    gate = AcCoupledGate(capacitor_f=68e-9, resistor_ohm=100e3, drive_v=3.3, threshold_v=0.65)
    assert gate.on_time_s() == pytest.approx(11.048e-3, rel=1e-3)
    # Capacitor still holding 1 V: ln(2.3 / 0.65) = 1.2637 -> 8.593 ms.
    assert gate.on_time_s(charged_v=1.0) == pytest.approx(8.593e-3, rel=1e-3)
    # The datasheet's highest threshold, 1.45 V: ln(3.3 / 1.45) = 0.8224 -> 5.592 ms, still past 5 ms pulses.
    assert AcCoupledGate(threshold_v=1.45).on_time_s() == pytest.approx(5.592e-3, rel=1e-3)
    # Held high for a second: one conducting segment of that length, then nothing.
    durations, levels = gate.schedule([1.0], [1])
    assert levels == [1.0, 0.0]
    assert durations[0] == pytest.approx(11.048e-3, rel=1e-3)
    assert sum(durations) == pytest.approx(1.0)


def test_a_short_low_leaves_the_ac_coupled_gate_part_charged():
    gate = AcCoupledGate()
    rc = 6.8e-3
    # High 20 ms: the capacitor reaches 3.3 (1 - e^(-20/6.8)); low 5 ms: times e^(-5/6.8).
    charged = 3.3 * (1 - math.exp(-20 / 6.8)) * math.exp(-5 / 6.8)
    durations, levels = gate.schedule([20e-3, 5e-3, 20e-3], [1, 0, 1])
    on = [d for d, lv in zip(durations, levels) if lv == 1.0]
    assert on[1] == pytest.approx(rc * math.log((3.3 - charged) / 0.65), rel=1e-9)
    assert on[1] < on[0]


@pytest.mark.parametrize("name", ["aa-resistor", "usb-resistor", "aa-sink", "aa-direct"])
def test_without_a_limit_a_stuck_gate_overheats_the_wire(name):
    circuit = Circuit.preset(name, WIRE)
    assert stuck_high_peak_c(None, WIRE, circuit, 30.0, duration_s=1.0) > MAX_C


def test_the_ac_coupled_gate_alone_does_not_bound_a_runaway_toggle():
    circuit = Circuit.preset("aa-resistor", WIRE)
    gate_only = HardwareLimit("aa-resistor", ac_gate=AcCoupledGate()).worst_corner()
    # One pulse when stuck: safe.
    assert stuck_high_peak_c(gate_only, WIRE, circuit, 30.0) <= MAX_C
    # Toggled at 20 kHz and 80 % duty the capacitor sits at its mean and the gate stays above threshold.
    assert worst_runaway(gate_only, WIRE, circuit, 30.0, periods_s=(50e-6,), duties=(0.8,))[2] > MAX_C


@pytest.mark.parametrize("name", SAFE_PRESETS)
def test_the_chosen_limit_holds_the_wire_in_the_design_air(name):
    limit = preset_limit(name, WIRE)
    assert limit.safe
    judged = judge_limit(limit, WIRE, name, 30.0)
    assert judged["stuck_high_c"] <= MAX_C
    assert judged["runaway_c"] <= MAX_C


def test_in_40_c_air_only_a_limit_sized_for_it_holds():
    circuit = Circuit.preset("aa-resistor", WIRE)
    sized_30 = preset_limit("aa-resistor", WIRE).worst_corner()
    sized_40 = preset_limit("aa-resistor", WIRE, design_air_c=40.0)
    # A toggle just under the 30 C limit's trip point, in 40 C air.
    duty = sized_30.replica.lower_fraction * 0.99
    assert worst_runaway(sized_30, WIRE, circuit, 40.0, periods_s=(20e-3,), duties=(duty,))[2] > MAX_C
    judged = judge_limit(sized_40, WIRE, circuit, 40.0)
    assert judged["stuck_high_c"] <= MAX_C
    assert judged["runaway_c"] <= MAX_C


def test_aa_direct_cannot_be_made_safe_this_way():
    limit = preset_limit("aa-direct", WIRE)
    assert not limit.safe
    assert "cannot be made safe" in limit.note
    assert stuck_high_peak_c(limit.worst_corner(), WIRE, Circuit.preset("aa-direct", WIRE), 30.0) > MAX_C


def test_the_claimed_worst_runaway_is_the_hottest_of_a_sweep():
    circuit = Circuit.preset("aa-resistor", WIRE)
    limit = preset_limit("aa-resistor", WIRE).worst_corner()
    edge = limit.replica.upper_fraction
    periods = (2e-3, 10e-3, 60e-3)
    duties = (0.02, edge * 0.995, edge * 1.005, 0.3)
    # Each pattern on its own, toggled by hand: 4 s of toggling, then 0.5 s stuck high.
    peaks = []
    for period in periods:
        for duty in duties:
            n = math.ceil(4.0 / period)
            logic = ([period * duty, period * (1 - duty)] * n + [0.5], [1, 0] * n + [1])
            peaks.append(peak_c(WIRE, circuit, limit.schedule(*logic), 30.0))
    claimed = worst_runaway(limit, WIRE, circuit, 30.0, periods_s=periods, duties=duties)
    assert claimed[2] == pytest.approx(max(peaks), abs=1e-6)
    # A duty just under the trip point is where the limit lets the most heat through.
    assert claimed[1] == pytest.approx(edge * 0.995)
    # The default sweep finds at least as hot a pattern as any of these probes.
    rows = runaway_sweep(limit, WIRE, circuit, 30.0)
    assert max(r[2] for r in rows) >= max(peaks) - 0.5
