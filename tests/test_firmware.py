"""The controller firmware itself, run on the host behind a pseudo-terminal.

Frames go over a real pty with pyserial; what the outputs do is read from the
emulated ``machine`` pins (host_machine), not from the firmware's own report.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
import threading
import time
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import serial
from hypothesis import given, settings
from hypothesis import strategies as st

from tactilize.actuators import frames as P
from tactilize.actuators.sma import build_envelope
from tactilize.boardhost import host_machine
from tactilize.boardhost.emulator import ControllerEmulator, load_firmware

fw = load_firmware()
PIN0, PIN1 = fw.CHANNEL_PINS


class Link:
    """A bare host end: pyserial plus the host decoder, one request at a time."""

    def __init__(self, device: str):
        self.ser = serial.Serial(device, timeout=0.5)
        self.dec = P.FrameDecoder()
        self.seq = 0

    def send_raw(self, data: bytes) -> None:
        self.ser.write(data)

    def read_frame(self, timeout_s: float = 5.0) -> P.Frame | None:
        deadline = time.monotonic() + timeout_s
        pending: list[P.Frame] = []
        while time.monotonic() < deadline:
            pending += self.dec.feed(self.ser.read(max(1, self.ser.in_waiting)))
            if pending:
                return pending[0]
        return None

    def request(self, command: int, payload: bytes = b"") -> P.Frame:
        self.seq = (self.seq + 1) & 0xFF
        self.send_raw(P.encode_frame(self.seq, command, payload))
        reply = self.read_frame()
        assert reply is not None, "no reply from the controller"
        assert reply.seq == self.seq
        return reply

    def set(self, channel: int, f_hz: float, w_s: float, amp: float = 1.0) -> P.Frame:
        return self.request(P.Command.SET, P.encode_set_channel(channel, f_hz, w_s, amp))

    def close(self) -> None:
        self.ser.close()


@pytest.fixture
def emu():
    host_machine.reset()
    events: list[dict] = []
    lock = threading.Lock()

    def on_change(ev: dict) -> None:
        ev = dict(ev, seen_s=time.monotonic())
        with lock:
            events.append(ev)

    e = ControllerEmulator(on_change=on_change, assume_cold=True).start()
    e.events = events  # type: ignore[attr-defined]
    yield e
    e.stop()
    host_machine.reset()


def _pulses(pin, since_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(starts [s, perf_counter], widths [s]) of the high pulses the pin made."""
    starts, widths, rise = [], [], None
    for t, kind, p, d in list(host_machine.events):
        if p != pin or kind != "gpio" or "value" not in d or t < since_s:
            continue
        if d["value"] and rise is None:
            rise = t
        elif not d["value"] and rise is not None:
            starts.append(rise)
            widths.append(t - rise)
            rise = None
    return np.array(starts), np.array(widths)


def _train(pin, link, n: int = 12, timeout_s: float = 20.0) -> tuple[float, float]:
    """(median interval [s], median width [s]) of the next ``n`` pulses on ``pin``,
    heartbeats kept coming meanwhile (the deadline is a bound only)."""
    since = time.perf_counter()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and len(_pulses(pin, since)[0]) < n + 1:
        assert link.request(P.Command.HEARTBEAT).command == P.Command.ACK
        time.sleep(0.02)
    starts, widths = _pulses(pin, since)
    assert len(starts) > n, f"{len(starts)} pulses on GP{pin}"
    return float(np.median(np.diff(starts))), float(np.median(widths))


@pytest.fixture
def link(emu):
    lk = Link(emu.device)
    yield lk
    lk.close()


def test_set_round_trip_drives_the_gate_pin(emu, link):
    reply = link.set(0, 120.0, 300e-6)
    assert reply.command == P.Command.ACK
    assert reply.payload[0] == P.Command.SET
    interval_s, width_s = _train(PIN0, link)
    # medians: a loaded host may hold a thread up now and then
    assert interval_s == pytest.approx(1 / 120.0, rel=0.25)
    assert 300e-6 <= width_s < 1e-3  # busy-waited: never shorter than asked
    assert host_machine.pin_state(PIN0)["mode"] == "gpio"  # no PWM slice on a gate pin
    assert len(_pulses(PIN1)[0]) == 0
    status = P.decode_status(link.request(P.Command.STATUS).payload)
    assert status.channels[0] == P.ChannelStatus(True, 120.0, 300e-6, 1.0)
    assert not status.channels[1].on
    assert status.max_frequency_hz == 300.0 and status.watchdog_s == 0.2
    on = [e for e in emu.events if e["on"]]
    assert on[0]["channel"] == 0 and on[0]["frequency_hz"] == 120.0 and on[0]["pulse_width_us"] == 300.0


def test_two_channels_run_different_frequencies(emu, link):
    link.set(0, 120.0, 300e-6)
    link.set(1, 250.0, 150e-6)
    assert _train(PIN0, link)[0] == pytest.approx(1 / 120.0, rel=0.25)
    assert _train(PIN1, link)[0] == pytest.approx(1 / 250.0, rel=0.25)


def test_bad_checksum_is_nakked_and_changes_nothing(emu, link):
    link.set(0, 100.0, 300e-6)
    frame = bytearray(P.encode_frame(42, P.Command.SET, P.encode_set_channel(0, 200.0, 300e-6, 1.0)))
    frame[-1] ^= 0xFF
    link.send_raw(bytes(frame))
    reply = link.read_frame()
    assert reply is not None and reply.command == P.Command.NAK and reply.seq == 42
    assert P.decode_nak(reply.payload)[0] == P.NakReason.BAD_CHECKSUM
    assert _train(PIN0, link)[0] == pytest.approx(1 / 100.0, rel=0.25)
    assert P.decode_status(link.request(P.Command.STATUS).payload).frames_bad == 1


@pytest.mark.parametrize(
    "f_hz, w_s, refused",
    [
        (301.0, 300e-6, P.Refused.FREQUENCY),
        (0.5, 300e-6, P.Refused.FREQUENCY),
        (100.0, 6e-3, P.Refused.PULSE_WIDTH),
        (100.0, 5e-6, P.Refused.PULSE_WIDTH),
        (250.0, 3e-3, P.Refused.DUTY),  # 75 %: no room to cool in the period
        (150.0, 1e-3, P.Refused.ENERGY),  # 15 %: within every shape limit, too much heat
    ],
)
def test_hard_limits_are_refused_and_the_old_drive_kept(emu, link, f_hz, w_s, refused):
    link.set(0, 80.0, 500e-6)
    reply = link.set(0, f_hz, w_s)
    assert reply.command == P.Command.NAK
    assert P.decode_nak(reply.payload) == (P.NakReason.REFUSED_LIMIT, refused)
    interval_s, width_s = _train(PIN0, link)
    assert interval_s == pytest.approx(1 / 80.0, rel=0.25) and 500e-6 <= width_s < 2e-3


def test_limit_edges_are_accepted(emu, link):
    assert link.set(0, 300.0, 10e-6).command == P.Command.ACK
    assert link.set(1, 1.0, 5e-3).command == P.Command.ACK
    # the energy limit is the host's envelope for the wire and circuit on the board
    env = build_envelope()
    w = env.max_pulse_width_s(50.0)
    assert link.set(0, 50.0, w * 0.999).command == P.Command.ACK
    reply = link.set(0, 50.0, w * 1.01)
    assert P.decode_nak(reply.payload) == (P.NakReason.REFUSED_LIMIT, P.Refused.ENERGY)


def test_unknown_command_and_bad_payload(emu, link):
    reply = link.request(0x55)
    assert P.decode_nak(reply.payload)[0] == P.NakReason.UNKNOWN_COMMAND
    reply = link.request(P.Command.SET, b"\x00\x01")
    assert P.decode_nak(reply.payload)[0] == P.NakReason.BAD_PAYLOAD
    reply = link.set(5, 100.0, 3e-4)
    assert P.decode_nak(reply.payload) == (P.NakReason.BAD_PAYLOAD, P.Refused.CHANNEL)


def test_stop_turns_everything_off(emu, link):
    link.set(0, 100.0, 3e-4)
    link.set(1, 150.0, 3e-4)
    assert link.request(P.Command.STOP).command == P.Command.ACK
    assert host_machine.pin_state(PIN0)["mode"] == "gpio" and host_machine.pin_state(PIN0)["value"] == 0
    assert host_machine.pin_state(PIN1)["mode"] == "gpio" and host_machine.pin_state(PIN1)["value"] == 0
    offs = [e for e in emu.events if not e["on"]]
    assert {(e["channel"], e["reason"]) for e in offs} == {(0, "stop"), (1, "stop")}


class BoardClock:
    """The firmware's millisecond ticks, moved by hand: the watchdog's window is
    tested on the board's own clock, not on how fast a loaded host runs threads."""

    def __init__(self, monkeypatch, start_ms: int = 1_000):
        from tactilize.firmware import tactile_frames

        self.ms = start_ms
        monkeypatch.setattr(fw, "_ticks_ms", lambda: self.ms)
        monkeypatch.setattr(tactile_frames, "_ticks_ms", lambda: self.ms)


@pytest.fixture
def board(monkeypatch):
    """A Controller on the host pins, fed and ticked by the test on a hand clock:
    (controller, clock, output changes as (ms, channel, on, reason))."""
    host_machine.reset()
    clock = BoardClock(monkeypatch)
    changes: list[tuple[int, int, bool, str]] = []
    sent: list[bytes] = []
    ctl = fw.Controller(sent.append, on_change=lambda ch, on, f, w, why: changes.append((clock.ms, ch, bool(on), why)),
                        assume_cold=True)
    ctl.sent = sent  # type: ignore[attr-defined]
    yield ctl, clock, changes
    ctl.all_off("exit")
    host_machine.reset()


def _run_loop(ctl, clock, until_ms: int, every_ms: int = fw.POLL_MS, feed=None) -> None:
    """The main loop's passes up to ``until_ms``: one tick at least every POLL_MS
    (``read(POLL_MS)`` returns by then on the board), with ``feed(ms)``'s bytes."""
    while clock.ms < until_ms:
        clock.ms += every_ms
        data = feed(clock.ms) if feed is not None else b""
        if data:
            ctl.feed(data)
        ctl.tick()


def test_watchdog_turns_outputs_off_within_250_ms_of_silence(board):
    ctl, clock, changes = board
    ctl.feed(P.encode_frame(1, P.Command.SET, P.encode_set_channel(0, 120.0, 300e-6, 1.0)))
    ctl.feed(P.encode_frame(2, P.Command.SET, P.encode_set_channel(1, 60.0, 400e-6, 1.0)))
    last_frame_ms = clock.ms
    _run_loop(ctl, clock, last_frame_ms + 190)
    assert not [c for c in changes if not c[2]], "off before 190 ms of silence"
    _run_loop(ctl, clock, last_frame_ms + 400)
    offs = [c for c in changes if not c[2]]
    assert sorted((ch, why) for _, ch, _, why in offs) == [(0, "watchdog"), (1, "watchdog")]
    silence_ms = max(ms for ms, *_ in offs) - last_frame_ms
    assert fw.WATCHDOG_MS < silence_ms <= fw.WATCHDOG_MS + fw.POLL_MS <= 250
    for pin in (PIN0, PIN1):
        hw = host_machine.pin_state(pin)
        assert hw["mode"] == "gpio" and hw["value"] == 0
    # the next ACK tells the host that the watchdog fired
    ctl.sent.clear()
    ctl.feed(P.encode_frame(3, P.Command.HEARTBEAT))
    ack = P.FrameDecoder().feed(b"".join(ctl.sent))[0]
    assert ack.command == P.Command.ACK and ack.payload[1] & P.FLAG_WATCHDOG_TRIPPED


def test_watchdog_over_the_serial_port(emu, link):
    # End to end through the pty: silence turns both outputs off and the next
    # ACK says so (when, to the millisecond, is the test above's, on the board's clock).
    link.set(0, 120.0, 300e-6)
    link.set(1, 60.0, 400e-6)
    deadline = time.monotonic() + 30.0  # a bound only: a loaded machine is slow
    while time.monotonic() < deadline and sum(1 for e in emu.events if not e["on"]) < 2:
        time.sleep(0.005)
    offs = [e for e in emu.events if not e["on"]]
    assert [e["reason"] for e in offs] == ["watchdog", "watchdog"]
    for pin in (PIN0, PIN1):
        hw = host_machine.pin_state(pin)
        assert hw["mode"] == "gpio" and hw["value"] == 0
    ack = link.request(P.Command.HEARTBEAT)
    assert ack.payload[1] & P.FLAG_WATCHDOG_TRIPPED
    assert P.decode_status(link.request(P.Command.STATUS).payload).watchdog_tripped


def test_heartbeats_keep_the_outputs_on(board):
    ctl, clock, changes = board
    ctl.feed(P.encode_frame(1, P.Command.SET, P.encode_set_channel(0, 120.0, 300e-6, 1.0)))
    # a heartbeat every 150 ms of the board's clock for 2 s: under the watchdog's 200 ms
    _run_loop(ctl, clock, clock.ms + 2_000,
              feed=lambda ms: P.encode_frame(2, P.Command.HEARTBEAT) if ms % 150 == 0 else b"")
    assert not [c for c in changes if not c[2]]
    # the train still runs: its next pulse's timer is armed
    assert ctl.channels[0].mode == "timed" and ctl.channels[0].timer is not None
    # and without them the same loop trips it: the heartbeats above did the work
    _run_loop(ctl, clock, clock.ms + 400)
    assert [why for _, _, on, why in changes if not on] == ["watchdog"]


def test_a_corrupt_length_cannot_starve_the_watchdog(board):
    # A start byte with a long length would swallow the following heartbeats
    # if the firmware waited for it to complete; it gives up after FRAME_TIMEOUT_MS.
    ctl, clock, changes = board
    ctl.feed(P.encode_frame(1, P.Command.SET, P.encode_set_channel(0, 120.0, 300e-6, 1.0)))
    ctl.feed(bytes((P.START, 64, 0, 0)))
    _run_loop(ctl, clock, clock.ms + 1_000,
              feed=lambda ms: P.encode_frame(1, P.Command.HEARTBEAT) if ms % 40 == 0 else b"")
    assert not [c for c in changes if not c[2]]


def test_slow_trains_use_a_timer_with_exact_pulse_width(emu, link):
    link.set(1, 5.0, 1e-3)
    # The first pulse of a 5 Hz train is due 200 ms in, as long as the watchdog
    # (also 200 ms) waits: keep the heartbeats coming, as a host does.  The
    # deadline is a bound only; a loaded machine may be slow to run the timer.
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and "last_pulse_s" not in host_machine.pin_state(PIN1):
        assert link.request(P.Command.HEARTBEAT).command == P.Command.ACK
        time.sleep(0.03)
    width = host_machine.pin_state(PIN1).get("last_pulse_s")
    assert width is not None, "the timer never pulsed the pin"
    # busy-waited: never shorter than asked; the upper bound allows host scheduling
    # (a busy machine can preempt the emulator mid-pulse for tens of milliseconds)
    assert 1e-3 <= width < 100e-3
    ev = [e for e in emu.events if e["on"] and e["channel"] == 1][0]
    assert ev["frequency_hz"] == 5.0 and ev["pulse_width_us"] == 1000.0


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200))
def test_firmware_crc_equals_host_crc(data):
    assert fw.crc16(data) == P.crc16_ccitt(data)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 255), st.integers(0, 255), st.binary(max_size=P.MAX_PAYLOAD)), max_size=5),
    st.binary(max_size=60),
    st.integers(0, 5),
)
def test_firmware_decoder_agrees_with_host_decoder(frames, garbage, where):
    stream = b"".join(P.encode_frame(s, c, p) for s, c, p in frames)
    cut = min(len(stream), where * 7)
    data = stream[:cut] + garbage + stream[cut:]
    got_fw: list[P.Frame] = []
    bad_fw: list[int] = []
    dec_fw = fw.Decoder(lambda s, c, p: got_fw.append(P.Frame(s, c, p)), bad_fw.append)
    dec_fw.feed(data)
    while dec_fw.buf:  # a silence: expire everything held back
        dec_fw.expire(dec_fw.pending_since_ms + 10 * fw.FRAME_TIMEOUT_MS)
    dec_host = P.FrameDecoder()
    got_host = dec_host.feed(data)
    while len(dec_host):
        got_host += dec_host.expire()
    assert got_fw == got_host
    assert len(bad_fw) == dec_host.crc_errors


# ------------------------------------------------------------ what docs/firmware.md flashes

def test_the_flashed_files_are_exactly_the_firmware_folder():
    """docs/firmware.md's mpremote line copies every module of tactilize/firmware and nothing else
    (the host's tools live in tactilize/boardhost), and the path it prints is that folder."""
    doc = (Path(__file__).resolve().parents[1] / "docs" / "firmware.md").read_text("utf-8")
    copied = dict(re.findall(r"cp (\S+\.py) :(\S+\.py)", doc))
    assert copied.get("controller.py") == "main.py"
    assert all(src == dst for src, dst in copied.items() if src != "controller.py")
    command = re.search(r'python -c "(import importlib\.resources[^"]+)"', doc)
    assert command is not None
    printed = subprocess.run([sys.executable, "-c", command.group(1)], capture_output=True, text=True, check=True)
    folder = Path(printed.stdout.strip()).parent
    on_disk = {p.name for p in folder.glob("*.py")} - {"__init__.py"}
    assert set(copied) == on_disk


# ------------------------------------------------------------ MicroPython compatibility

MICROPYTHON_MODULES = {"struct", "sys", "time", "math", "machine", "select", "micropython", "tactile_channel", "tactile_frames",
                       "tactile_events", "tactile_heat", "tactile_wire", "tactilize.firmware"}


@pytest.mark.parametrize("name", ["controller.py", "tactile_channel.py", "tactile_events.py", "tactile_frames.py", "tactile_heat.py",
                                  "tactile_wire.py"])
def test_controller_source_uses_only_micropython_features(name):
    source = resources.files("tactilize.firmware").joinpath(name).read_text("utf-8")
    tree = ast.parse(source)
    for node in ast.walk(tree):
        assert not isinstance(node, ast.JoinedStr), f"f-string at line {node.lineno}"
        assert not isinstance(node, ast.AnnAssign), f"annotation at line {node.lineno}"
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            assert node.returns is None and all(a.annotation is None for a in node.args.args), node.name
        if isinstance(node, ast.Import):
            assert {a.name for a in node.names} <= MICROPYTHON_MODULES, node.names
        if isinstance(node, ast.ImportFrom):
            assert node.module in MICROPYTHON_MODULES, node.module
        if isinstance(node, ast.Attribute):
            # bytearray/bytes .find and int.to_bytes are missing or partial on some ports
            assert node.attr not in {"find", "to_bytes", "from_bytes", "monotonic"} or _in_compat_block(node), node.attr
        if isinstance(node, (ast.With, ast.AsyncWith, ast.Lambda)) and isinstance(node, ast.AsyncWith):
            raise AssertionError("async with")


def _in_compat_block(node: ast.AST) -> bool:
    # time.monotonic appears only in the CPython fallback, guarded by getattr.
    return getattr(node, "attr", "") == "monotonic"


def test_an_irregular_train_jitters_around_its_mean_frequency_on_the_board(emu, link):
    """The SET frame's regularity reaches the board, which places each pulse by a
    one-shot timer at (k + j u_k) periods: an irregular texture stays irregular on
    the real controller."""
    starts: list[float] = []

    def on_pin(t_s, kind, pin_id, detail):
        if pin_id == PIN0 and detail.get("mode") == "gpio" and detail.get("value") == 1:
            starts.append(t_s)

    f_hz = 20.0
    host_machine.add_listener(on_pin)
    try:
        assert link.request(P.Command.SET, P.encode_set_channel(0, f_hz, 1e-3, 1.0, regularity=0.0)).command == P.Command.ACK
        deadline = time.monotonic() + 20.0
        while len(starts) < 41 and time.monotonic() < deadline:
            assert link.request(P.Command.HEARTBEAT).command == P.Command.ACK
            time.sleep(0.05)
        link.request(P.Command.STOP)
    finally:
        host_machine.remove_listener(on_pin)
    iv = np.diff(np.array(starts[:41]))
    assert iv.size == 40
    # same mean frequency (positions locked to the grid), intervals CV near 0.6/sqrt(6)
    assert 1 / iv.mean() == pytest.approx(f_hz, rel=0.05)
    assert iv.std() / iv.mean() > 0.15
    assert iv.min() > 0.35 / f_hz  # never closer than 0.4 period (less host scheduling noise)


def test_the_set_frame_carries_regularity_only_when_irregular():
    even = P.encode_set_channel(0, 80.0, 3e-4, 1.0)
    assert even == P.encode_set_channel(0, 80.0, 3e-4, 1.0, 1.0) and len(even) == 11
    irregular = P.encode_set_channel(0, 80.0, 3e-4, 1.0, 0.25)
    assert len(irregular) == 13
    assert P.decode_set_channel(irregular).regularity_q16 == round(0.25 * 65535)
    assert P.decode_set_channel(even).regularity_q16 == P.REGULARITY_EVEN
    with pytest.raises(ValueError):
        P.encode_set_channel(0, 80.0, 3e-4, 1.0, -0.5)
