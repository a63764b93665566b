"""The SMA wire model: physics checks, energy conservation, following, the safety envelope."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tactilize.actuators.sma import (
    FOLLOW_THRESHOLD_M,
    Circuit,
    WireModel,
    WireSpec,
    build_envelope,
    simulate,
    simulate_drive,
    steady_cycle,
)
from tactilize.errors import TactilizeError, WireError
from tactilize.mapping import Drive
from tactilize.synthesis import pulse_train

SPEC = WireSpec.preset("75um")


@pytest.fixture(scope="module")
def envelope():
    return build_envelope(SPEC)  # the aa-resistor circuit


# ----------------------------------------------------------------- the wire's numbers


def test_preset_matches_the_facts_sheet():
    # docs/references.md, section 2: 226 / 181 ohm per metre, tau 0.3 .. 0.6 s, 0.68 J/m latent.
    per_m = SPEC.replace(length_m=1.0)
    assert per_m.resistance_austenite_ohm == pytest.approx(226, rel=0.01)
    assert per_m.resistance_martensite_ohm == pytest.approx(181, rel=0.01)
    assert 0.3 <= SPEC.time_constant_s <= 0.6
    assert per_m.latent_j == pytest.approx(0.68, rel=0.02)
    # ~2 W per metre holds 45 K above ambient
    assert per_m.conductance_w_k * 45 == pytest.approx(2.0, rel=0.05)
    assert [WireSpec.preset(n).diameter_m for n in ("50um", "75um", "100um")] == [50e-6, 75e-6, 100e-6]
    thin, thick = WireSpec.preset("50um"), WireSpec.preset("100um")
    assert thin.convection_w_m2_k > SPEC.convection_w_m2_k > thick.convection_w_m2_k


def test_bad_wire_requests_raise_one_error_type():
    with pytest.raises(WireError):
        WireSpec.preset("33um")
    with pytest.raises(WireError, match="75um"):  # a change of a field the wire does not have
        WireSpec.preset("75um", colour="red")
    with pytest.raises(WireError, match="aa-resistor"):  # ...nor the circuit
        Circuit.preset("aa-resistor", colour="red")
    assert WireSpec.preset("75um", length_m=0.05).length_m == 0.05
    assert Circuit.preset("aa-resistor", supply_v=2.5).supply_v == 2.5
    with pytest.raises(WireError):
        WireSpec(length_m=-1.0)
    with pytest.raises(WireError):
        WireSpec(austenite_start_c=80.0)
    with pytest.raises(TactilizeError):
        simulate([0.1, float("nan")], 1e-5)
    with pytest.raises(TactilizeError):
        simulate([0.1, 0.2], 0.0)
    with pytest.raises(TactilizeError):
        simulate_drive(Drive(100.0, 20e-3), 1.0)  # width longer than the period


# ----------------------------------------------------------------- an independent reference


def euler_reference(spec: WireSpec, drive: Drive, current_a: float, T0: float, xi0: float, t_end: float, dt: float):
    """Forward Euler on the heat balance in its C_eff form, 1 us steps, voltage source.

    References
    ----------
    .. [1] docs/references.md, section 2 (heat balance).
    """
    C, hA, Lat, Ta = spec.heat_capacity_j_k, spec.conductance_w_k, spec.latent_j, spec.ambient_c
    RA, RM = spec.resistance_austenite_ohm, spec.resistance_martensite_ohm
    As, Af, Ms, Mf = spec.austenite_start_c, spec.austenite_finish_c, spec.martensite_start_c, spec.martensite_finish_c
    aA, aM = math.pi / (Af - As), math.pi / (Ms - Mf)
    V2 = (current_a * RM) ** 2

    def heat_curve(T):  # major heating curve h_A and its slope
        if T <= As:
            return 1.0, 0.0
        if T >= Af:
            return 0.0, 0.0
        return 0.5 * (1 + math.cos(aA * (T - As))), -0.5 * aA * math.sin(aA * (T - As))

    def cool_curve(T):  # h_M: 1 at M_f, 0 at M_s
        if T <= Mf:
            return 1.0, 0.0
        if T >= Ms:
            return 0.0, 0.0
        return 0.5 * (1 + math.cos(aM * (T - Mf))), -0.5 * aM * math.sin(aM * (T - Mf))

    T, xi, branch, k = T0, xi0, 0, 1.0
    n = int(round(t_end / dt))
    out_T, out_xi = np.empty(n + 1), np.empty(n + 1)
    out_T[0], out_xi[0] = T, xi
    period, width = drive.period_s, drive.pulse_width_s
    for i in range(n):
        t = (i + 0.5) * dt
        on = (t % period) < width
        R = RA + (RM - RA) * xi
        P = V2 / R if on else 0.0
        F = P - hA * (T - Ta)
        d = 1 if F > 0 else -1
        if d != branch:
            branch = d
            if d > 0:
                h, _ = heat_curve(T)
                k = xi / h if h > 1e-12 else 0.0
            else:
                h, _ = cool_curve(T)
                k = (1 - xi) / (1 - h) if 1 - h > 1e-12 else 0.0
        if branch > 0:
            _, s = heat_curve(T)
            slope = k * s
        else:
            _, s = cool_curve(T)
            slope = k * s  # d/dT of 1 - k (1 - h_M) = k h_M'
        T += dt * F / (C - Lat * slope)
        if branch > 0:
            xi = k * heat_curve(T)[0]
        else:
            xi = 1 - k * (1 - cool_curve(T)[0])
        xi = min(1.0, max(0.0, xi))
        out_T[i + 1], out_xi[i + 1] = T, xi
    return out_T, out_xi


def test_segment_integrator_agrees_with_brute_force_euler():
    drive = Drive(50.0, 1e-3)
    T0, xi0, t_end = 69.6, 0.85, 0.2
    ref_T, ref_xi = euler_reference(SPEC, drive, 0.5, T0, xi0, t_end, 1e-6)
    # The reference's source: I into the relaxed wire from a stiff voltage (R_source -> 0).
    stiff = Circuit("stiff", "voltage", supply_v=0.5 * SPEC.resistance_martensite_ohm, source_ohm=1e-9)
    res = simulate_drive(drive, t_end, SPEC, circuit=stiff, dt_s=1e-6, initial_temperature_c=T0, initial_martensite_fraction=xi0)
    assert res.temperature_c.shape == ref_T.shape
    assert np.max(np.abs(res.temperature_c - ref_T)) < 0.02
    assert np.max(np.abs(res.martensite_fraction - ref_xi)) < 0.003
    # the run really crossed the band both ways (minor loops, not a flat line)
    assert ref_xi.max() - ref_xi.min() > 0.05


# ----------------------------------------------------------------- energy


@pytest.mark.parametrize("circuit", ["aa-resistor", "aa-sink", "stiff"])
def test_energy_is_conserved_within_one_percent(circuit):
    stiff = Circuit("stiff", "voltage", supply_v=0.5 * SPEC.resistance_martensite_ohm, source_ohm=1e-9)
    circ = stiff if circuit == "stiff" else Circuit.preset(circuit, SPEC)
    dt = 1e-5
    # 3 s of 50 Hz pulses with a bias: through warm-up into the band.
    res = simulate_drive(Drive(50.0, 1.1e-3), 3.0, SPEC, circuit=circ, bias_level=0.02, dt_s=dt)
    xi = res.martensite_fraction
    assert xi.min() < 0.9  # it did transform, so the latent term matters
    # Independent accounts from the traces: I^2 R with R mixed from the phases (docs/references.md, section 2).
    R = SPEC.resistance_austenite_ohm + (SPEC.resistance_martensite_ohm - SPEC.resistance_austenite_ohm) * 0.5 * (xi[1:] + xi[:-1])
    on = res.current_a > 0
    level = np.where(res.current_a > 0.5 * res.current_a.max(), 1.0, 0.02)
    amps = np.array([circ.current_at(r) for r in R])
    electrical = float(np.sum(np.where(on, level * amps**2 * R, 0.0)) * dt)
    T = res.temperature_c
    convected = float(SPEC.conductance_w_k * np.sum(0.5 * (T[1:] + T[:-1]) - SPEC.ambient_c) * dt)
    stored = SPEC.heat_capacity_j_k * (T[-1] - T[0])
    latent = SPEC.latent_j * (xi[0] - xi[-1])
    assert electrical == pytest.approx(stored + convected + latent, rel=0.01)
    assert res.electrical_j == pytest.approx(electrical, rel=0.01)
    assert abs(res.energy_balance_error) < 1e-6


def test_circuits_set_the_current_not_the_wire():
    # two AA cells straight onto 3 mm of wire: several amperes (docs/references.md, section 8)
    direct = Circuit.preset("aa-direct", SPEC)
    assert 2.3 <= direct.current_at(SPEC.resistance_austenite_ohm) < direct.current_at(SPEC.resistance_martensite_ohm) <= 3.5
    # the series resistor brings it to the operating current, within 2 %
    res = Circuit.preset("aa-resistor", SPEC)
    assert res.current_at(SPEC.resistance_martensite_ohm) == pytest.approx(SPEC.rated_current_a, rel=0.02)
    # a sink holds its current whatever the wire, until the cells cannot feed it
    sink = Circuit.preset("aa-sink", SPEC)
    assert sink.current_at(SPEC.resistance_martensite_ohm) == sink.current_at(SPEC.resistance_austenite_ohm) == 0.5
    flat = sink.replace(supply_v=0.45)
    assert flat.current_at(SPEC.resistance_austenite_ohm) < 0.5
    # the worst heat is at least the heat at either phase
    for c in (direct, res, sink, flat):
        worst = c.max_power_w(SPEC)
        assert worst >= max(c.power_at(SPEC.resistance_martensite_ohm), c.power_at(SPEC.resistance_austenite_ohm)) - 1e-15
    with pytest.raises(WireError):
        Circuit.preset("nine-volt")
    with pytest.raises(WireError):
        Circuit("bad", "voltage", supply_v=3.0, source_ohm=0.0)
    with pytest.raises(WireError):
        Circuit("bad", "current", current_a=-1.0)


# ----------------------------------------------------------------- following


def test_too_much_duty_holds_the_wire_contracted():
    res = simulate_drive(Drive(50.0, 2e-3), 6.0, SPEC, current_a=0.5)  # 10 % duty at the rated current
    s = res.summary()
    assert not s["follows"]
    assert s["mean_temperature_c"] > SPEC.austenite_finish_c
    assert s["mean_martensite_fraction"] < 0.01
    assert s["displacement_pp_um"] < FOLLOW_THRESHOLD_M * 1e6


def test_weak_current_stays_cold():
    # docs/references.md, section 2 (operating point): 120 mA at 5 % duty keeps the wire near 29 C.
    res = simulate_drive(Drive(50.0, 1e-3), 4.0, SPEC, current_a=0.12)
    s = res.summary()
    assert 27 < s["mean_temperature_c"] < 31
    assert s["displacement_pp_um"] == 0.0 and not s["follows"]


def test_steady_cycle_matches_a_long_run():
    f, w, cur = 100.0, 0.55e-3, SPEC.rated_current_a
    c = steady_cycle(f, w, cur, SPEC)
    model = WireModel(SPEC, Circuit.ideal_current(cur))
    edges: list = []
    n = int(40 * f)
    model.run([w, 1 / f - w] * n, [1.0, 0.0] * n, edges=edges)
    assert c.peak_temperature_c == pytest.approx(edges[-2][0], abs=0.1)
    assert c.martensite_start == pytest.approx(edges[-1][1], abs=0.02)


def test_sampled_current_agrees_with_exact_edges():
    drive = Drive(300.0, 150e-6)
    exact = simulate_drive(drive, 3.0, SPEC, current_a=SPEC.rated_current_a)
    sampled = simulate(pulse_train(drive, 3.0, 1 / 5e-6) * SPEC.rated_current_a, 5e-6, SPEC)
    assert exact.summary()["mean_temperature_c"] == pytest.approx(sampled.summary()["mean_temperature_c"], abs=0.05)


# ----------------------------------------------------------------- the envelope


def test_envelope_clamps_and_says_so(envelope):
    d = Drive(120.0, 0.9e-3)  # 10.8 % duty at the circuit's full current
    out = envelope.apply(d)
    assert out.pulse_width_s < d.pulse_width_s and "envelope" in out.clamped
    assert out.pulse_frequency_hz == d.pulse_frequency_hz and out.amplitude == d.amplitude
    ok = Drive(120.0, 0.2e-3)
    assert envelope.apply(ok) == ok
    assert envelope.apply(Drive.off()) == Drive.off()
    # its own bound on the peak is at the limit for what it lets through
    assert envelope.peak_bound_c(out) == pytest.approx(
        envelope.design_ambient_c + 0.95 * (SPEC.max_temperature_c - envelope.design_ambient_c))


def test_envelope_is_energy_on_the_circuit_configured(envelope):
    # shorter at higher frequency; the chopped switch heats linearly in its level
    widths = [envelope.max_pulse_width_s(f) for f in (1.0, 10.0, 100.0, 300.0)]
    assert all(a > b for a, b in zip(widths, widths[1:]))
    assert envelope.max_pulse_width_s(100.0, amplitude=0.3) == pytest.approx(envelope.max_pulse_width_s(100.0) / 0.3)
    # the same wire switched straight onto the cells may take far less
    direct = build_envelope(SPEC, "aa-direct")
    ratio = envelope.max_power_w / direct.max_power_w
    assert direct.max_pulse_width_s(100.0) == pytest.approx(envelope.max_pulse_width_s(100.0) * ratio)
    assert ratio < 0.1
    # a bias leaves less room for pulses
    assert envelope.max_pulse_energy_j(100.0, bias_level=0.02) < envelope.max_pulse_energy_j(100.0)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    log_f=st.floats(math.log(1.0), math.log(400.0)),
    duty=st.floats(0.001, 0.9),
    amplitude=st.floats(0.05, 1.0),
    circuit=st.sampled_from(["aa-resistor", "usb-resistor", "aa-sink", "aa-direct"]),
)
def test_whatever_the_envelope_lets_through_stays_under_its_temperature_limit(log_f, duty, amplitude, circuit):
    """A drive with no controller at all, only the envelope, on each circuit, open loop:
    the model's peak stays under the wire's limit (in the envelope's design air)."""
    f = math.exp(log_f)
    env = build_envelope(SPEC, circuit)
    drive = env.apply(Drive(f, duty / f, amplitude))
    if drive.is_off:
        return
    hot_air = SPEC.replace(ambient_c=env.design_ambient_c)
    # 4 s from the design air is past 7 time constants: the settled peak is reached.
    res = simulate_drive(drive, 4.0, hot_air, circuit=env.circuit, dt_s=1e-4)
    assert res.summary()["peak_temperature_c"] <= SPEC.max_temperature_c


def test_simulate_drive_reports_its_current_on_the_sample_grid():
    res = simulate_drive(Drive(200.0, 0.25e-3), 0.5, SPEC, current_a=SPEC.rated_current_a, dt_s=5e-6)
    cur = res.current_a
    assert cur.size == 100_000 and res.time_s.size == 100_001
    assert set(np.unique(cur)) == {0.0, SPEC.rated_current_a}
    assert np.count_nonzero(cur) == 100 * 50  # 100 pulses of 50 samples
    assert res.pulse_starts_s.size == 100
    assert np.allclose(np.diff(res.pulse_starts_s), 5e-3)
