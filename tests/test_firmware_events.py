"""Scheduled pulses on the board (protocol 4), on a virtual-time board judged by the wire model.

Every frame lands at an exact simulated instant (tests/_virtual_board.py), so the
pulses on the pin can be compared with their scheduled times to the microsecond.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, target
from hypothesis import strategies as st

from tactilize.actuators import frames as P
from tactilize.actuators.sma import Circuit, WireSpec, circuit_names
from tactilize.firmware import tactile_events as E

from _virtual_board import PIN0, Board, fw, peak_on_wire

MAX_C = WireSpec.resolve(None).max_temperature_c


def _clock(board) -> int:
    board.send(P.Command.PING, P.encode_ping(1))
    pong = [f for f in board.replies() if f.command == P.Command.PONG][-1]
    return P.decode_pong(pong.payload).board_us


def _events(board, channel, base_us, pulses):
    board.send(P.Command.EVENTS, P.encode_events(channel, base_us, pulses))


def _rises(board, pin=PIN0):
    return [t for t, level in board.vm.edges.get(pin, []) if level]


def _counts(board, channel=0) -> P.EventCounts:
    board.send(P.Command.PING, P.encode_ping(2))
    pong = [f for f in board.replies() if f.command == P.Command.PONG][-1]
    return P.decode_pong(pong.payload).counts[channel]


def test_pulses_start_on_their_board_time(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    board.until(0.1)
    now = _clock(board)
    pulses = [(0, 10_000, 300), (1, 25_000, 300), (2, 47_000, 500)]
    _events(board, 0, now + 5_000, pulses)
    assert [f.command for f in board.replies()] == [P.Command.ACK]
    board.until(0.2)
    rises = _rises(board)
    assert now == 100_000  # the board's clock started with the board
    expected = [now + 5_000 + off for _, off, _ in pulses]
    assert len(rises) == 3
    assert max(abs(r - e) for r, e in zip(rises, expected)) <= 2  # to the microsecond (the timer's grain)
    assert _counts(board) == P.EventCounts(3, 0, 0, 0, 0)


def test_a_resent_frame_never_doubles_a_pulse(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    board.until(0.05)
    base = _clock(board) + 2_000
    frame = [(40, 0, 400), (41, 8_000, 400), (42, 16_000, 400)]
    _events(board, 0, base, frame)
    board.until(0.05 + 0.0035)  # the first has fired, the second not
    _events(board, 0, base, frame)  # the ACK was lost: the host sends it again
    board.until(0.05 + 0.0045)
    _events(board, 0, base, frame)
    board.until(0.2)
    assert len(_rises(board)) == 3
    c = _counts(board)
    assert c.fired == 3 and c.repeated == 2


def test_a_late_frame_drops_the_pulses_already_past(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    board.until(0.05)
    now = _clock(board)
    # Sent 10 ms before now, say (a stalled link): the first two are past.
    _events(board, 0, now - 10_000, [(0, 0, 300), (1, 7_000, 300), (2, 14_000, 300)])
    board.until(0.1)
    rises = _rises(board)
    assert len(rises) == 1 and abs(rises[0] - (50_000 + 4_000)) <= 2
    c = _counts(board)
    assert (c.fired, c.late) == (1, 2)


def test_a_frame_replaces_what_is_not_yet_fired(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    board.until(0.05)
    base = _clock(board)
    _events(board, 0, base, [(0, 5_000, 300), (1, 20_000, 300), (2, 30_000, 300)])
    board.until(0.05 + 0.010)
    # The pen turned: the crossings at 20 and 30 ms will not happen; one at 25 ms will.
    _events(board, 0, base, [(3, 25_000, 300)])
    board.until(0.2)
    assert [r - 50_000 for r in _rises(board)] == [5_000, 25_000]


def test_a_set_stop_or_the_watchdog_ends_the_schedule(monkeypatch, tmp_path):
    for end in ("set", "stop", "watchdog"):
        board = Board(monkeypatch, Path(tempfile.mkdtemp(dir=tmp_path)))
        board.until(0.05)
        now = _clock(board)
        if end == "watchdog":
            # Due after the host has been silent for the watchdog's 200 ms.
            _events(board, 0, now + 250_000, [(0, 0, 300), (1, 10_000, 300)])
        else:
            _events(board, 0, now + 5_000, [(0, 0, 300), (1, 55_000, 300)])
        board.until(0.065)
        if end == "set":
            board.set(0, 0.0, 0.0)
        elif end == "stop":
            board.send(P.Command.STOP)
        board.until(0.5)
        assert len(_rises(board)) == (0 if end == "watchdog" else 1), end


def test_bad_event_frames_are_refused(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    now = _clock(board)
    _events(board, 0, now + 1000, [(0, 0, 6_000)])  # 6 ms: beyond the 5 ms hard limit
    _events(board, 2, now + 1000, [(0, 0, 300)])  # no channel 2
    _events(board, 0, now + 2_000_000, [(0, 0, 300)])  # 2 s ahead
    board.send(P.Command.EVENTS, P.encode_events(0, now, [(0, 500, 300)])[:-1])  # a cut entry
    naks = [P.decode_nak(f.payload) for f in board.replies()]
    assert naks == [(P.NakReason.REFUSED_LIMIT, P.Refused.PULSE_WIDTH), (P.NakReason.BAD_PAYLOAD, P.Refused.CHANNEL),
                    (P.NakReason.BAD_PAYLOAD, P.Refused.NONE), (P.NakReason.BAD_PAYLOAD, P.Refused.NONE)]
    board.until(0.1)
    assert _rises(board) == []


def _schedule_peak(pulses_us, end_us, circuit):
    """The wire model's peak under pulses played exactly as asked (no gate)."""
    edges = sorted(pulses_us)
    durs, levels, t = [], [], 0.0
    for start, width in edges:
        if start > t:
            durs.append((start - t) * 1e-6), levels.append(0.0)
        durs.append(width * 1e-6), levels.append(1.0)
        t = start + width
    durs.append(max(1.0, end_us - t) * 1e-6), levels.append(0.0)
    return peak_on_wire(durs, levels, circuit)


def test_the_gate_holds_a_schedule_that_would_overheat(monkeypatch, tmp_path):
    """5 ms pulses every 10 ms for half a second would take the wire far past its
    maximum; the board shortens and skips them and the wire stays under it."""
    board = Board(monkeypatch, tmp_path)
    board.until(0.01)
    t0 = _clock(board) + 1000
    asked = []
    for k in range(0, 50, 6):
        pulses = [(k + i, 10_000 * i, 5_000) for i in range(6)]
        _events(board, 0, t0 + 10_000 * k, pulses)
        asked += [(10_000 + t0 + 10_000 * (k + i), 5_000) for i in range(6)]
        board.until(0.01 + 0.01 * (k + 6))
        board.send(P.Command.HEARTBEAT)
    board.until(0.6)
    assert _schedule_peak(asked, 700_000, "aa-resistor") > MAX_C  # the test can fail
    c = _counts(board)
    assert c.shortened + c.skipped > 0
    assert board.peak_c() <= MAX_C


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(circuit=st.sampled_from(circuit_names()),
       frames=st.lists(st.tuples(st.floats(0.0, 0.08),  # wait before the frame [s]
                                 st.integers(-5_000, 20_000),  # base after now [us]
                                 st.lists(st.tuples(st.integers(0, 12_000), st.integers(10, 5_000)), max_size=9),
                                 st.integers(0, 1), st.booleans()),  # channel, ids fresh or repeated
                       min_size=1, max_size=25),
       bias=st.floats(0.0, 1.0))
def test_no_schedule_at_any_cadence_overheats_the_wire(monkeypatch, circuit, frames, bias):
    """Any scheduled pulses (widths to 5 ms, gaps from none), in frames at any
    instants, resent or fresh, over any HOLD bias the board allows: the wire model
    run on what the pins did stays under the wire's maximum."""
    tmp = Path(tempfile.mkdtemp())
    try:
        board = Board(monkeypatch, tmp, circuit)
        limits = board.ctl.limits
        board.send(P.Command.HOLD, P.encode_hold(0, 0.0, bias * limits.budget * limits.h, 0.0))
        t, next_id = 0.0, 0
        for wait, ahead, pulses, channel, fresh in frames:
            t += wait
            board.until(t)
            board.send(P.Command.HEARTBEAT)
            entries, off = [], 0
            for gap, width in pulses:
                off = min(0xFFFF, off + gap)
                entries.append((next_id, off, width))
                next_id += 1 if fresh else 0
            _events(board, channel, _clock(board) + ahead, entries)
        board.until(t + 0.1)
        for channel in (0, 1):
            pins = (fw.CHANNEL_PINS[channel], fw.BIAS_PINS[channel])
            board.vm.finish()
            durs, levels = board.vm.channel_levels(*pins, board.vm.now_us)
            peak = peak_on_wire(durs, levels, Circuit.resolve(circuit, WireSpec.resolve(None)))
            target(peak, label=f"peak of wire {channel} [C]")
            assert peak <= MAX_C, (channel, peak)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def test_two_starts_are_never_closer_than_the_bands_top(monkeypatch, tmp_path):
    board = Board(monkeypatch, tmp_path)
    board.until(0.01)
    base = _clock(board) + 1000
    _events(board, 0, base, [(0, 0, 100), (1, 1_000, 100), (2, 2_000, 100), (3, 4_000, 100)])
    board.until(0.1)
    rises = _rises(board)
    assert min(b - a for a, b in zip(rises, rises[1:])) >= E.MIN_GAP_US
    assert len(rises) == 2 and _counts(board).skipped == 2


@pytest.mark.parametrize("wrap_at", [2**32 - 3_000])
def test_the_boards_clock_wraps_at_32_bits(monkeypatch, tmp_path, wrap_at):
    board = Board(monkeypatch, tmp_path)
    board.ctl.clock.us = wrap_at  # as if the board had run 71 minutes
    now = _clock(board)
    _events(board, 0, now + 1_000, [(0, 0, 300), (1, 5_000, 300)])  # the second after the wrap
    board.until(0.05)
    assert [r for r in _rises(board)] == [1_000, 6_000]
