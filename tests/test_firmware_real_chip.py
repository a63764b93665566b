"""The firmware against what a real RP2040 running MicroPython does, probed as an attacker would.

Each case below heated the wire far past its maximum, or crashed or silenced the firmware,
before the firmware learned the chip's semantics (docs/safety.md, "The wire"; docs/references.md,
section 8 (RP2040 PWM slice), (MicroPython ticks)). Every peak is the host's wire model
(latent heat included) run on what the pins did, against the wire's maximum, on every circuit
preset.  The board's clock is MicroPython's: ticks wrap at 2^30 us, ``ticks_diff`` is
modular and ``ticks_add`` refuses intervals of 2^29 us or more.
"""

from __future__ import annotations

import pytest

from tactilize.actuators import frames as P
from tactilize.actuators.sma import Circuit, WireSpec, circuit_names
from tactilize.firmware import tactile_wire as W

from _virtual_board import Board, fw

SPEC = WireSpec.preset("75um")
MAX_C = SPEC.max_temperature_c
CIRCUITS = circuit_names()
HALF_TICKS_US = 1 << 29


def _run(board, until_s: float, every_s: float = 0.05) -> None:
    """Heartbeats every ``every_s`` until the board's clock reads ``until_s``."""
    t = board.now_s
    while t < until_s:
        t = min(until_s, t + every_s)
        board.send(P.Command.HEARTBEAT)
        board.until(t)


def _widest(board, f_hz: float, channel: int = 0) -> float:
    """The widest pulse [s] the board acknowledges at ``f_hz`` (the host's best attack)."""
    w = min(5e-3, 0.5 / f_hz)
    while w >= 10e-6:
        board.set(channel, f_hz, w)
        if board.replies()[-1].command == P.Command.ACK:
            return w
        w *= 0.95
    return 0.0


def _widths_us(board, channel: int = 0) -> list[int]:
    """The width [us] of every pulse the channel's gate pin made."""
    edges = board.vm.edges.get(fw.CHANNEL_PINS[channel], [])
    out, rise = [], None
    for t, level in edges:
        if level and rise is None:
            rise = t
        elif not level and rise is not None:
            out.append(t - rise)
            rise = None
    return out


def _watch_gate_pads(monkeypatch, board) -> list[int]:
    """Every gate pin whose pad is switched to a PWM slice from now on: a slice
    carries its counter over a stop and a new PWM(), and latches TOP and compare
    only at a wrap, so its first pulse is not one the heat gate counted."""
    switched: list[int] = []
    sio = board.chip.sio

    def watching(gpio, func=None, out=None, oe=None):
        if func == "pwm" and gpio in fw.CHANNEL_PINS:
            switched.append(gpio)
        return sio(gpio, func=func, out=out, oe=oe)

    monkeypatch.setattr(board.chip, "sio", watching)
    return switched


def _events_payload(channel: int, base_us: int, pulses: list[tuple[int, int, int]]) -> bytes:
    return P.encode_events(channel, base_us & 0xFFFFFFFF, pulses)


# ------------------------------------------------------------------ 1. a slice left near its wrap


@pytest.mark.parametrize("circuit", CIRCUITS)
def test_a_train_stopped_near_its_wrap_then_the_widest_slow_one_stays_under_the_maximum(monkeypatch, tmp_path, circuit):
    """300 Hz / 10 us stopped just before its period ends, then the widest 20 Hz SET
    stopped right after its first pulse, again and again: on a PWM slice whose
    counter survives the stop, 173-178 wide pulses a second and 405-415 C."""
    board = Board(monkeypatch, tmp_path, circuit)
    slices = _watch_gate_pads(monkeypatch, board)
    w20 = _widest(board, 20.0)
    board.send(P.Command.STOP)
    assert w20 > 0
    for _ in range(120):
        board.set(0, 300.0, 10e-6)
        board.until(board.now_s + 1 / 300 - 20e-6)
        board.send(P.Command.STOP)
        board.set(0, 20.0, w20)
        board.until(board.now_s + w20 + 50e-6)
        board.send(P.Command.STOP)
    board.replies()
    wide = [w for w in _widths_us(board) if w > 100]
    assert len(wide) / board.now_s <= 21  # not a wide pulse every few ms
    assert board.peak_c(0) <= MAX_C
    assert slices == []


# ------------------------------------------------------------------ 2. toggled frames


def _stopper(kind: str, board) -> None:
    if kind == "set-off":
        board.set(0, 0.0, 0.0, 0.0)
    elif kind == "stop":
        board.send(P.Command.STOP)
    else:
        now = board.ctl.clock.now()
        board.send(P.Command.EVENTS, _events_payload(0, now + 40_000, [(7, 0, 10)]))


@pytest.mark.parametrize("circuit", CIRCUITS)
@pytest.mark.parametrize("stopper", ["set-off", "stop", "events"])
@pytest.mark.parametrize("cadence_ms", [1, 3, 5])
def test_toggled_frames_never_fire_uncounted_pulses(monkeypatch, tmp_path, circuit, stopper, cadence_ms):
    """SET on, then off (a zero SET, STOP or EVENTS) every few ms: each fresh slice's
    first pulse came 1 ms after it was made, unseen by the heat estimate (759 C)."""
    board = Board(monkeypatch, tmp_path, circuit)
    slices = _watch_gate_pads(monkeypatch, board)
    trains = [(f, _widest(board, f)) for f in (20.0, 100.0, 300.0)]
    board.send(P.Command.STOP)
    k = 0
    while board.now_s < 1.5:
        f, w = trains[k % len(trains)]
        board.set(0, f, w)
        board.until(board.now_s + cadence_ms / 2e3)
        _stopper(stopper, board)
        board.until(board.now_s + cadence_ms / 2e3)
        k += 1
    board.replies()
    assert board.peak_c(0) <= MAX_C
    assert slices == []


# ------------------------------------------------------------------ 3. and 4. the ticks wrap


@pytest.mark.parametrize("circuit", CIRCUITS)
def test_an_events_base_far_behind_is_late_not_a_crash(monkeypatch, tmp_path, circuit):
    """A base 2^29 us or more behind the board's clock made ticks_add raise
    OverflowError out of Controller.feed, and main() exited."""
    board = Board(monkeypatch, tmp_path, circuit)
    _run(board, 0.2)
    board.replies()
    now = board.ctl.clock.now()
    for behind in (HALF_TICKS_US, HALF_TICKS_US + 12345, (1 << 31) - 1, 1 << 31):
        board.send(P.Command.EVENTS, _events_payload(0, now - behind, [(1, 0, 500), (2, 100, 500)]))
    got = board.replies()
    assert [f.command for f in got] == [P.Command.ACK] * 4
    assert not any(f.payload[1] & fw.FLAG_FIRMWARE_ERROR for f in got)
    assert board.ctl.errors == 0
    assert board.ctl.channels[0].queue.counts[3] == 8  # every pulse counted late, none fired
    assert board.pulse_count(0) == 0


@pytest.mark.parametrize("circuit", CIRCUITS)
@pytest.mark.parametrize("idle_s", [540.0, 800.0])
def test_a_slow_train_long_after_the_last_pulse_plays(monkeypatch, tmp_path, idle_s, circuit):
    """A 5 Hz SET 537 s after the channel's last pulse raised OverflowError (ticks_add
    of a period from a tick that had wrapped); later it played nothing for 2 s."""
    board = Board(monkeypatch, tmp_path, circuit, start_us=(1 << 30) - 3_000_000)
    width_s = min(1e-3, _widest(board, 5.0), _widest(board, 20.0))  # what every preset admits
    board.set(0, 20.0, width_s)
    board.replies()
    _run(board, 0.3)
    board.send(P.Command.STOP)
    before = board.pulse_count(0)
    assert before > 5
    board.until(0.3 + idle_s)  # silence: the watchdog has nothing left to turn off
    board.set(0, 5.0, width_s)
    _run(board, board.now_s + 2.0)
    got = board.replies()
    assert all(f.command == P.Command.ACK for f in got)
    assert board.ctl.errors == 0
    assert 9 <= board.pulse_count(0) - before <= 11


@pytest.mark.parametrize("circuit", CIRCUITS)
@pytest.mark.parametrize("idle_s", [9 * 60.0, 18 * 60.0])
def test_a_stroke_long_after_the_last_pulse_plays_every_scheduled_pulse(monkeypatch, tmp_path, idle_s, circuit):
    """9-18 min after a channel's last pulse a stroke played 0 of 20 EVENTS pulses:
    the gap to the last pulse read -473,741,824 us, closer than the 3 ms rule."""
    board = Board(monkeypatch, tmp_path, circuit)
    now = board.ctl.clock.now()
    board.send(P.Command.EVENTS, _events_payload(0, now + 2_000, [(900, 0, 800)]))
    _run(board, 0.1)
    assert board.pulse_count(0) == 1
    board.until(0.1 + idle_s)
    eid = 1
    for frame in range(5):
        now = board.ctl.clock.now()
        pulses = [(eid + k, 2_000 + 10_000 * k, 800) for k in range(4)]
        eid += 4
        board.send(P.Command.EVENTS, _events_payload(0, now, pulses))
        board.until(board.now_s + 0.04)
    _run(board, board.now_s + 0.1)
    counts = board.ctl.channels[0].queue.counts
    assert counts[0] == 21 and counts[2] == 0, counts  # fired, none skipped
    assert board.pulse_count(0) == 21


def test_no_exception_escapes_the_loop_and_the_next_reply_says_so(monkeypatch, tmp_path):
    """Whatever raises inside the firmware: outputs off, estimates at the budget,
    the loop goes on, and the next reply carries the error flag until a STOP."""
    board = Board(monkeypatch, tmp_path)
    board.set(0, 100.0, 0.2e-3)
    _run(board, 0.2)
    assert board.ctl.channels[0].on
    ch = board.ctl.channels[0]

    def broken(*a, **k):
        raise MemoryError("out of heap")

    monkeypatch.setattr(ch.hold, "step", broken)
    board.send(P.Command.HOLD, P.encode_hold(0, 1e-5, 0.0, 0.6))
    _run(board, 0.4)
    assert not ch.on and ch.heat.rise_k >= ch.heat.budget * 0.5
    flags = [f.payload[1] for f in board.replies() if f.command == P.Command.ACK]
    assert flags and flags[-1] & fw.FLAG_FIRMWARE_ERROR
    starts = [s for s in board.pulse_starts_us(0) if s > 0.25e6]
    assert not starts  # nothing fired after the error
    monkeypatch.undo()
    board.send(P.Command.STOP)
    board.send(P.Command.HEARTBEAT)
    got = board.replies()
    assert got[0].payload[1] & fw.FLAG_FIRMWARE_ERROR and not got[1].payload[1] & fw.FLAG_FIRMWARE_ERROR


def test_a_timer_callback_that_raises_turns_the_channel_off(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    board.set(0, 100.0, 0.2e-3)
    _run(board, 0.1)
    assert board.ctl.channels[0].on
    ch = board.ctl.channels[0]

    def broken(now, us):
        raise ValueError("bad pin")

    monkeypatch.setattr(ch, "_pulse", broken)
    _run(board, 0.3)
    assert not ch.on
    assert board.ctl.errors >= 1
    assert board.replies()[-1].payload[1] & fw.FLAG_FIRMWARE_ERROR


# ------------------------------------------------------------------ 5. a common sensing error


def _sensed_common(board, k: float, r_wire: float = 0.6, channel: int = 0) -> None:
    """Current and rail both read k times the truth (a wrong ADC reference): every
    plausibility check passes, since the resistance V / I comes out right."""
    i = Circuit.resolve(board.circuit, SPEC).current_at(r_wire)
    board.vm.adc[fw.SENSE_ADC_PINS[channel]] = k * i / W.DEFAULT_AMPS_PER_COUNT
    board.vm.adc[fw.RAIL_ADC_PIN] = k * i * (r_wire + W.DEFAULT_PATH_OHM[channel]) / W.RAIL_VOLTS_PER_COUNT


@pytest.mark.parametrize("circuit", CIRCUITS)
@pytest.mark.parametrize("k", [0.85, 0.5, 0.4])
def test_a_sensing_error_common_to_current_and_rail_never_loosens_the_limit(monkeypatch, tmp_path, circuit, k):
    board = Board(monkeypatch, tmp_path, circuit)
    _sensed_common(board, k)
    board.set(0, 40.0, 0.3e-3)  # a small train: the board measures during it
    _run(board, 0.5)
    for f in (20.0, 50.0, 100.0, 300.0):
        w = _widest(board, f)
        assert w <= board.ctl.limits.max_width_s(f, 0.0, board.ctl.limits.p_max) * 1.0001
        _run(board, board.now_s + 1.5)
    assert board.peak_c(0) <= MAX_C


# ------------------------------------------------------------------ 6. power-up on a hot wire


@pytest.mark.parametrize("circuit", CIRCUITS)
def test_power_up_on_a_hot_wire_admits_energy_only_as_it_cools(monkeypatch, tmp_path, circuit):
    """A brown-out, a re-plugged cable, a soft or watchdog reset: the wire may be at
    87 C and reset_cause() may read power-on.  The estimate starts at the budget."""
    board = Board(monkeypatch, tmp_path, circuit)
    board.reset("power")  # reset_cause() reads power-on: no hint at all
    assert board.vm.reset_cause() == 1
    for f in (1.0, 20.0, 300.0):  # the widest single pulses first, then the hottest trains
        _widest(board, f)
        _run(board, board.now_s + 1.0)
    hot = SPEC.max_temperature_c - 3.0
    assert board.peak_c(0, start_c=hot) <= MAX_C
    # and the gate did let pulses through once the estimate had cooled
    assert board.pulse_count(0) >= 30


# ------------------------------------------------------------------ 7. a room warmer than the design air


def _chip_reads(board, chip_c: float) -> None:
    """The die's temperature [C], read by ADC input 4 through the datasheet's line."""
    board.chip.chip_temp_c = chip_c


def _hottest(board) -> None:
    for f in (20.0, 100.0, 300.0):
        _widest(board, f)
        _run(board, board.now_s + 2.0)


@pytest.mark.parametrize("circuit", CIRCUITS)
def test_a_board_made_for_a_warm_room_stays_under_the_maximum_in_it(monkeypatch, tmp_path, circuit):
    board = Board(monkeypatch, tmp_path, circuit, design_air_c=40.0)
    _hottest(board)
    assert board.peak_c(0, air_c=40.0) <= MAX_C


@pytest.mark.parametrize("circuit", CIRCUITS)
def test_the_chips_sensor_lowers_the_budget_in_a_warm_room(monkeypatch, tmp_path, circuit):
    board = Board(monkeypatch, tmp_path, circuit)
    _chip_reads(board, 41.0)  # the die runs at or above the air around it
    _hottest(board)
    assert board.ctl.air.air_c == pytest.approx(41.0, abs=0.2)
    assert board.peak_c(0, air_c=40.0) <= MAX_C


def test_a_chip_reading_never_raises_the_budget(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    budget = board.ctl.limits.budget
    for chip_c in (10.0, -60.0, 200.0):
        _chip_reads(board, chip_c)
        _run(board, board.now_s + 1.1)
        assert board.ctl.limits.budget == budget
