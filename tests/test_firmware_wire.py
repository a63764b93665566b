"""The wire on the board, judged by the wire model: re-sent and changed SETs,
the running heat estimate, the whole-hertz PWM, jittered trains, a faulty sense
path.  The firmware runs on a virtual-time board (tests/_virtual_board.py), so
every frame lands at an exact simulated instant and nothing waits on the clock.
"""

from __future__ import annotations

import shutil
import struct
import tempfile
from pathlib import Path

import pytest
from hypothesis import settings, target
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, rule

from tactilize.actuators import frames as P
from tactilize.actuators.sma import Circuit, WireModel, WireSpec, build_envelope, circuit_names
from tactilize.actuators.sma.envelope import drive_jitter
from tactilize.drive import Drive
from tactilize.firmware import tactile_wire as W

from _virtual_board import Board, fw, peak_on_wire

SPEC = WireSpec.resolve(None)
MAX_C = SPEC.max_temperature_c
PIN0, PIN1 = fw.CHANNEL_PINS
BIAS0, BIAS1 = fw.BIAS_PINS


# ------------------------------------------------------------------ re-sent SET frames


def _resent(board, f_hz, w_s, every_s, seconds, regularity=None, channel=0):
    t = 0.0
    while t < seconds:
        board.set(channel, f_hz, w_s, 1.0, regularity)
        t += every_s
        board.until(t)


@pytest.mark.parametrize("every_s, regularity", [(0.05, 0.2), (0.02, 0.2), (0.05, None)])
def test_a_resent_set_does_not_multiply_the_pulse_rate(monkeypatch, tmp_path, every_s, regularity):
    """The issue's case: 2 Hz / 5 ms (irregular: checked bound 52.7 C) re-sent every
    50 ms fired a pulse per frame, 20 pulses/s and 147 C on the wire model."""
    board = Board(monkeypatch, tmp_path)
    _resent(board, 2.0, 5e-3, every_s, 3.0, regularity)
    assert all(f.command == P.Command.ACK for f in board.replies())
    n = board.pulse_count()
    assert 5 <= n <= 7, n  # 2 pulses/s for 3 s
    assert board.peak_c() <= MAX_C


@pytest.mark.parametrize("f_hz", [1.0, 5.0, 12.0, 19.0])
@pytest.mark.parametrize("wobble", [0.0, 0.03])
def test_a_slow_train_fires_under_the_renderers_resends(monkeypatch, tmp_path, f_hz, wobble):
    """Trains below 20 Hz were restarted by every SET: at the renderer's 0.1 s
    refresh they never fired (a silent texture).  The same drive resent, or one
    that changes a little with every refresh (a pen's speed), keeps its rate."""
    board = Board(monkeypatch, tmp_path)
    t, k = 0.0, 0
    while t < 3.0:
        board.set(0, f_hz * (1.0 + wobble * (-1) ** k), 1e-3)
        t, k = t + 0.1, k + 1
        board.until(t)
    n = board.pulse_count()
    assert abs(n - 3.0 * f_hz) <= 1.5 + 3.0 * f_hz * wobble, n


def test_after_any_start_the_board_treats_the_wire_as_hot(monkeypatch, tmp_path):
    """A board cannot know how long it was off (a watchdog or soft reset, a
    brown-out, a re-plugged cable): the estimate starts at the budget, whatever
    reset_cause() says, and the first pulses wait until it has cooled enough."""
    cold = Board(monkeypatch, tmp_path)
    assert cold.ctl.channels[0].heat.rise_k == 0.0
    board = Board(monkeypatch, tmp_path, after_watchdog_reset=True)
    heat = board.ctl.channels[0].heat
    assert heat.rise_k == heat.budget
    board.set(0, 10.0, 1e-3)
    t = 0.0
    while t < 0.5:
        board.send(P.Command.HEARTBEAT)
        t += 0.05
        board.until(t)
    rises = [t for t, level in board.vm.edges[PIN0] if level]
    # 1 ms at the circuit's worst is 2.2 K: the budget must have fallen that much (21 ms)
    assert rises and rises[0] >= 0.02e6
    assert len(rises) >= 3


# ------------------------------------------------------------------ any frames, any timing


class FrameSequences(RuleBasedStateMachine):
    """Frames at chosen instants and cadences (resends, silences, changes between
    even and irregular, slow and fast trains, holds, pairs, stops, scheduled
    pulses with bases far behind and ahead, toggles down to 1 ms, idles past the
    ticks' wrap, resets of every kind at any moment, a wrong ADC reference) on
    the chip model, whose clock may start just before the ticks wrap, with a
    sense path that reads what the circuit gives the wire (or nothing); after it
    all, the wire model run on what the pins did stays under the maximum, and no
    exception reached the firmware's loop."""

    def __init__(self):
        super().__init__()
        self.mp = pytest.MonkeyPatch()
        self.tmp = Path(tempfile.mkdtemp())
        self.board = None
        self.t = 0.0
        self.last: dict[int, bytes] = {}

    @initialize(circuit=st.sampled_from(circuit_names()), phase=st.one_of(st.none(), st.floats(0.0, 1.0)),
                sag=st.floats(0.5, 1.0), before_wrap_s=st.one_of(st.none(), st.floats(0.0, 3.0)))
    def start(self, circuit, phase, sag, before_wrap_s):
        nominal = Circuit.resolve(circuit, SPEC)
        self.circ = nominal.replace(supply_v=nominal.supply_v * sag)
        start_us = 0 if before_wrap_s is None else (1 << 30) - int(before_wrap_s * 1e6)
        self.board = Board(self.mp, self.tmp, circuit, start_us=start_us)
        r_m, r_a = SPEC.resistance_martensite_ohm, SPEC.resistance_austenite_ohm
        amps = 0.0 if phase is None else self.circ.current_at(r_m + phase * (r_a - r_m))
        vm = self.board.vm
        vm.adc[fw.SENSE_ADC_PINS[0]] = vm.adc[fw.SENSE_ADC_PINS[1]] = min(65535, amps / W.DEFAULT_AMPS_PER_COUNT)
        vm.adc[fw.RAIL_ADC_PIN] = amps * (0.6 + W.DEFAULT_PATH_OHM[0]) / W.RAIL_VOLTS_PER_COUNT

    def _go(self, dt):
        self.t += dt
        self.board.until(self.t)

    @rule(channel=st.integers(0, 1), f=st.floats(1.0, 300.0),
          w=st.one_of(st.floats(10e-6, 5e-3), st.floats(0.5, 1.0).map(lambda x: -x)),
          amp=st.sampled_from([0.3, 1.0]), regularity=st.one_of(st.none(), st.floats(0.0, 0.99)))
    def set(self, channel, f, w, amp, regularity):
        if w < 0:  # a share of the largest width the board's bound allows: the edge, where it matters
            limits = self.board.ctl.limits
            j = 0.0 if regularity is None else 0.6 * (1.0 - regularity)
            w = min(5e-3, max(10e-6, -w * limits.max_width_s(f, 0.0, limits.p_max, j)))
        payload = P.encode_set_channel(channel, f, w, amp, regularity)
        self.last[channel] = payload
        self.board.send(P.Command.SET, payload)

    @rule(channel=st.integers(0, 1), every=st.sampled_from([0.005, 0.02, 0.05, 0.1, 0.2]),
          seconds=st.floats(0.05, 1.5))
    def resend(self, channel, every, seconds):
        payload = self.last.get(channel)
        end = self.t + seconds
        while self.t < end:
            if payload is not None:
                self.board.send(P.Command.SET, payload)
            else:
                self.board.send(P.Command.HEARTBEAT)
            self._go(every)

    @rule(seconds=st.floats(0.0, 3.0), heartbeats=st.booleans())
    def wait(self, seconds, heartbeats):
        end = self.t + seconds
        while self.t < end:
            if heartbeats:
                self.board.send(P.Command.HEARTBEAT)
            self._go(min(0.05, end - self.t + 1e-6))

    @rule(channel=st.integers(0, 1), e=st.floats(0.0, 2e-3), b=st.one_of(st.floats(0.0, 0.5), st.floats(0.5, 1.0)),
          r=st.floats(0.0, 1.0), share=st.booleans())
    def hold(self, channel, e, b, r, share):
        if share:  # a bias near what the board's bound allows (the wire at its budget)
            b = min(b, 1.0) * self.board.ctl.limits.budget * self.board.ctl.limits.h
        self.board.send(P.Command.HOLD, P.encode_hold(channel, e, b, r))

    @rule(f=st.floats(1.0, 300.0), w=st.floats(10e-6, 5e-3), soa=st.floats(0.0, 0.2))
    def pair(self, f, w, soa):
        self.board.send(P.Command.PAIR, P.encode_pair(soa, (f, w, 1.0), (f, w, 1.0)))

    @rule()
    def stop(self):
        self.board.send(P.Command.STOP)

    @rule(channel=st.integers(0, 1), f=st.sampled_from([20.0, 100.0, 300.0]), share=st.floats(0.5, 1.0),
          stopper=st.sampled_from(["set-off", "stop", "events"]), every_ms=st.integers(1, 5),
          seconds=st.floats(0.05, 1.0))
    def toggle(self, channel, f, share, stopper, every_ms, seconds):
        limits = self.board.ctl.limits
        w = min(5e-3, 0.5 / f, max(10e-6, share * limits.max_width_s(f, 0.0, limits.p_max)))
        end = self.t + seconds
        while self.t < end:
            self.board.send(P.Command.SET, P.encode_set_channel(channel, f, w, 1.0))
            self._go(every_ms / 2e3)
            if stopper == "set-off":
                self.board.send(P.Command.SET, P.encode_set_channel(channel, 0.0, 0.0, 0.0))
            elif stopper == "stop":
                self.board.send(P.Command.STOP)
            else:
                now = self.board.ctl.clock.now()
                self.board.send(P.Command.EVENTS, P.encode_events(channel, now + 30_000, [(1, 0, 10)]))
            self._go(every_ms / 2e3)

    @rule(channel=st.integers(0, 1),
          base_s=st.one_of(st.floats(-2.0, 1.2), st.sampled_from([-(2.0 ** 29) / 1e6, -(2.0 ** 31) / 1e6,
                                                                  (2.0 ** 31 - 1) / 1e6, 600.0])),
          n=st.integers(1, 9), spacing_us=st.integers(0, 7000), width_us=st.integers(10, 5000),
          first_id=st.integers(0, 65000))
    def events(self, channel, base_s, n, spacing_us, width_us, first_id):
        base = self.board.ctl.clock.now() + int(base_s * 1e6)
        pulses = [((first_id + k) & 0xFFFF, min(65535, k * spacing_us), width_us) for k in range(n)]
        self.board.send(P.Command.EVENTS, P.encode_events(channel, base, pulses))

    @rule(kind=st.sampled_from(["status", "sense", "sense-v3", "ping", "heartbeat", "unknown"]),
          token=st.integers(0, 2**32 - 1))
    def ask(self, kind, token):
        if kind == "status":
            self.board.send(P.Command.STATUS)
        elif kind == "sense":
            self.board.send(P.Command.SENSE)
        elif kind == "sense-v3":
            self.board.send(P.Command.SENSE, P.SENSE_V3)
        elif kind == "ping":
            self.board.send(P.Command.PING, P.encode_ping(token))
        elif kind == "heartbeat":
            self.board.send(P.Command.HEARTBEAT)
        else:
            self.board.send(0x55, bytes([token & 0xFF]))

    @rule(seconds=st.sampled_from([540.0, 1100.0]))
    def idle_past_the_wrap(self, seconds):
        self._go(seconds)

    @rule(kind=st.sampled_from(["power", "watchdog", "soft"]), after_s=st.floats(0.0, 0.02))
    def reset(self, kind, after_s):
        self._go(after_s)
        self.board.reset(kind)

    @rule(k=st.sampled_from([0.4, 0.5, 0.85, 1.2]))
    def wrong_adc_reference(self, k):
        self.board.adc_reference_error(k)

    def teardown(self):
        try:
            if self.board is not None:
                self._go(0.3)  # the last pulses land and the watchdog ends it
                for channel in (0, 1):
                    self.board.vm.finish()
                    pins = ((PIN0, BIAS0), (PIN1, BIAS1))[channel]
                    durs, levels = self.board.vm.channel_levels(*pins, self.board.vm.now_us)
                    peak = peak_on_wire(durs, levels, self.circ)
                    target(peak, label=f"peak of wire {channel} [C]")  # search toward the hottest runs
                    assert peak <= MAX_C, (channel, peak)
                assert self.board.ctl.errors == 0
        finally:
            self.mp.undo()
            shutil.rmtree(self.tmp, ignore_errors=True)


FrameSequences.TestCase.settings = settings(max_examples=80, stateful_step_count=12, deadline=None)
test_no_frames_at_any_timing_overheat_the_wire = FrameSequences.TestCase


# ------------------------------------------------------------------ jittered trains


def _worst_jitter_peak(env, f_hz, energy_j, j):
    """An even train in its periodic state, then one pulse j periods early: every
    earlier pulse as late as the jitter allows and the last as early (the closest
    a jittered train brings its past heat to one pulse), on the wire model in the
    envelope's design air, with (next to) no latent heat and the circuit's
    worst heat at every temperature: the lumped heat balance the bound is
    derived from."""
    spec = env.spec.replace(latent_heat_j_kg=1e-9, ambient_c=env.design_ambient_c,
                            resistivity_austenite_ohm_m=env.spec.resistivity_martensite_ohm_m)
    period, w = 1.0 / f_hz, energy_j / env.max_power_w
    air = env.design_ambient_c
    r_hi = max(spec.resistance_martensite_ohm, spec.resistance_austenite_ohm)
    model = WireModel(spec, Circuit.ideal_current((env.max_power_w / r_hi) ** 0.5),
                      temperature_c=air)
    durs, levels = [], []
    for _ in range(int(12 * spec.time_constant_s * f_hz) + 2):  # 12 tau: the periodic state
        durs += [w, period - w]
        levels += [1.0, 0.0]
    durs[-1] -= j * period
    durs += [w, period]
    levels += [1.0, 0.0]
    edges: list = []
    model.run(durs, levels, edges=edges)
    return max(T for T, _ in edges)


@pytest.mark.parametrize("periods_per_tau", [0.5, 1.0])
def test_the_worst_jitter_stays_within_the_envelopes_bound(periods_per_tau):
    """The bound T_air + f E / hA + E / C is exact only for even trains: a jittered
    train's closest pulses ran about 3 % of the budget past it; with (1 + j) E / C
    the worst sequence stays at or below T_air + budget."""
    env = build_envelope(SPEC, "aa-resistor")
    f = 1.0 / (periods_per_tau * SPEC.time_constant_s)
    j = 0.6
    drive = Drive(f, 1e-3, 1.0, regularity=0.0)
    energy = env.max_pulse_width_s(f, 1.0, 0.0, drive_jitter(drive)) * env.max_power_w
    assert drive_jitter(drive) == pytest.approx(j)
    assert _worst_jitter_peak(env, f, energy, j) <= env.design_ambient_c + env.budget_k + 1e-6
    # what the bound allowed before (even trains' energy) runs past it
    old = env.max_pulse_energy_j(f)
    assert _worst_jitter_peak(env, f, old, j) > env.design_ambient_c + env.budget_k
    # the board's own limits give the same energy
    limits = W.WireLimits(W.DEFAULT_CONFIG)
    assert limits.max_width_s(f, 0.0, env.max_power_w, j) * env.max_power_w == pytest.approx(energy, rel=1e-9)


def test_a_train_never_runs_faster_than_it_was_checked_at(monkeypatch, tmp_path):
    """The energy check is made at the frequency asked, and a timed train's period is
    rounded up to the microsecond: the widest width the bound allows at 20.5 Hz is
    acknowledged, its pulses come no closer than 1 / 20.5 s, and a width past the
    bound is refused."""
    board = Board(monkeypatch, tmp_path)
    limits = board.ctl.limits
    w = limits.max_width_s(20.5, 0.0, limits.p_max)
    board.set(0, 20.5, w * 1.01)
    board.set(0, 20.5, w * 0.999)
    got = board.replies()
    assert P.decode_nak(got[0].payload) == (P.NakReason.REFUSED_LIMIT, P.Refused.ENERGY)
    assert got[1].command == P.Command.ACK
    t = 0.0
    while t < 1.0:
        t += 0.05
        board.send(P.Command.HEARTBEAT)
        board.until(t)
    starts = board.pulse_starts_us(0)
    assert len(starts) >= 19
    # anchored to the train's start (the first fired a timer's microsecond late)
    assert (starts[-1] - starts[0]) / (len(starts) - 1) >= 1e6 / 20.5 - 1
    assert min(b - a for a, b in zip(starts, starts[1:])) >= 1e6 / 20.5 - 2


# ------------------------------------------------------------------ a faulty sense path


def _sensed(board, gain, r_wire=0.6, channel=0):
    """The sense path reads ``gain`` times the current the circuit gives a wire of
    ``r_wire`` [ohm]; the rail reads true."""
    from tactilize.actuators.sma import Circuit
    i = Circuit.resolve(board.circuit, SPEC).current_at(r_wire)
    board.vm.adc[fw.SENSE_ADC_PINS[channel]] = gain * i / W.DEFAULT_AMPS_PER_COUNT
    board.vm.adc[fw.RAIL_ADC_PIN] = i * (r_wire + W.DEFAULT_PATH_OHM[channel]) / W.RAIL_VOLTS_PER_COUNT


def _measure_then(board, f_hz, w_s, seconds=0.5):
    t = 0.0
    board.set(0, 40.0, 0.3e-3)  # a small train: the board measures during it
    while t < seconds:
        board.send(P.Command.HEARTBEAT)
        t += 0.05
        board.until(t)
    board.replies()
    board.set(0, f_hz, w_s)
    board.send(P.Command.SENSE, P.SENSE_V3)
    while t < seconds + 1.0:
        board.send(P.Command.HEARTBEAT)
        t += 0.05
        board.until(t)
    return board.replies()


def test_a_sense_amplifier_reading_40_percent_is_a_fault(monkeypatch, tmp_path):
    """A gain-20 part where the gain-50 one belongs reads 40 %: 'a 10 ohm wire', a
    looser limit, and SET 40 Hz / 5 ms was acknowledged (264 C on the wire model).
    Now the reading is a fault: the worst-case bound refuses it, and the ACK and
    SENSE reply say so."""
    board = Board(monkeypatch, tmp_path)
    _sensed(board, 0.4)
    got = _measure_then(board, 40.0, 5e-3)
    assert P.decode_nak(got[0].payload) == (P.NakReason.REFUSED_LIMIT, P.Refused.ENERGY)
    report = P.decode_sense(got[1].payload)
    assert report.faults == (True, False)
    assert report.channels[0].resistance_ohm > 5  # what it would have believed
    assert got[-1].command == P.Command.ACK and got[-1].payload[1] & P.FLAG_SENSE_FAULT
    assert board.peak_c() <= MAX_C


def test_a_true_sense_path_is_no_fault_and_loosens_nothing_wrongly(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    _sensed(board, 1.0)
    got = _measure_then(board, 40.0, 5e-3)
    assert P.decode_nak(got[0].payload) == (P.NakReason.REFUSED_LIMIT, P.Refused.ENERGY)  # too hot anyway
    report = P.decode_sense(got[1].payload)
    assert report.faults == (False, False) and report.channels[0].count > 0
    assert report.channels[0].resistance_ohm == pytest.approx(0.6, abs=0.01)
    assert not got[-1].payload[1] & P.FLAG_SENSE_FAULT


@pytest.mark.parametrize("rail_gain", [0.5, 1.6])
def test_a_current_the_rail_cannot_drive_is_a_fault(monkeypatch, tmp_path, rail_gain):
    board = Board(monkeypatch, tmp_path)
    _sensed(board, 1.0)
    board.vm.adc[fw.RAIL_ADC_PIN] = board.vm.adc[fw.RAIL_ADC_PIN] * rail_gain
    got = _measure_then(board, 40.0, 0.3e-3)
    assert P.decode_sense(got[1].payload).faults == (True, False)


def test_an_older_hosts_sense_gets_the_reply_it_knows(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    board.send(P.Command.SENSE)
    board.send(P.Command.SENSE, P.SENSE_V3)
    old, new = board.replies()
    assert len(old.payload) == struct.calcsize(P.SENSE_FORMAT_V2) and P.decode_sense(old.payload).faults is None
    assert P.decode_sense(new.payload).faults == (False, False)


def test_a_calibration_out_of_range_is_a_fault(monkeypatch, tmp_path):
    cal = [(W.DEFAULT_AMPS_PER_COUNT * 2.5, 5.25), (W.DEFAULT_AMPS_PER_COUNT, 5.25)]
    (tmp_path / W.CAL_FILE).write_text(W.calibration_text(cal))
    board = Board(monkeypatch, tmp_path)
    board.send(P.Command.STATUS)
    board.send(P.Command.HEARTBEAT)
    got = board.replies()
    status = P.decode_status(got[0].payload)
    assert status.version >= 3 and status.sense_fault
    assert got[1].payload[1] & P.FLAG_SENSE_FAULT


def test_a_big_pulse_after_a_hot_bias_waits_for_the_wire_to_cool(monkeypatch, tmp_path):
    """Each frame within its bound, but not the way from one to the next: a hold
    whose bias keeps the wire at its budget, then an irregular 1 Hz train of the
    largest pulses its bound allows (aa-direct: 32 K each).  The first landed on
    the hot wire at once (110.1 C on the wire model, with or without the resend
    fix); the board's heat estimate holds it until the wire has cooled."""
    board = Board(monkeypatch, tmp_path, "aa-direct")
    limits = board.ctl.limits
    board.send(P.Command.HOLD, P.encode_hold(0, 0.0, 0.999 * limits.budget * limits.h, 0.0))
    t = 0.0
    for _ in range(60):  # 3 s: the bias brings the wire to its budget
        board.send(P.Command.HEARTBEAT)
        t += 0.05
        board.until(t)
    j = 0.6 * (1 - 0.5)  # an irregular train: its first pulse is due at once
    energy = limits.budget / (1.0 / limits.h + (1 + j) / limits.c)  # the bound at 1 Hz, no bias
    board.set(0, 1.0, 0.999 * energy / limits.p_max, 1.0, 0.5)
    for _ in range(30):
        board.send(P.Command.HEARTBEAT)
        t += 0.05
        board.until(t)
    assert all(f.command == P.Command.ACK for f in board.replies())
    assert board.pulse_count() >= 1
    assert board.peak_c() <= MAX_C


def test_a_late_timer_catches_up_without_a_burst(monkeypatch, tmp_path):
    """Retuning a PWM slice busy-waits an old period, and the other channel's
    timers wait with it: its irregular train then catches up with no two pulses
    closer than 0.4 period (on the emulator under load, late pulses came 1.2 ms
    apart), and keeps its mean rate."""
    board = Board(monkeypatch, tmp_path)
    board.set(1, 50.0, 0.5e-3, 1.0, 0.0)
    t, k = 0.0, 0
    while t < 4.0:
        board.set(0, (30.0, 31.0)[k % 2], 1e-3)  # each retune busy-waits one old period (33 ms)
        board.send(P.Command.HEARTBEAT)
        t, k = t + 0.06, k + 1
        board.until(t)
    starts = [s for s, level in board.vm.edges[PIN1] if level]
    gaps = [b - a for a, b in zip(starts, starts[1:])]
    assert min(gaps) >= 0.4 * 20_000 - 1, min(gaps)
    assert len(starts) == pytest.approx(200, abs=6)
    assert board.peak_c(1) <= MAX_C
