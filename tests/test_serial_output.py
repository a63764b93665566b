"""SerialOutput against the real firmware over a pseudo-terminal."""

from __future__ import annotations

import math

import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
import tty

import pytest

from tactilize.actuators import frames as P
from tactilize.actuators.factory import open_output
from tactilize.actuators.serial import SerialOutput
from tactilize.errors import OutputError, TactilizeError
from tactilize.boardhost import host_machine
from tactilize.boardhost.emulator import ControllerEmulator, load_firmware
from tactilize.mapping import ActuatorLimits, Drive
from _waiting import wait_for

fw = load_firmware()


class Identity:
    """An envelope that lets everything through (to reach the controller's limits)."""

    def apply(self, drive: Drive) -> Drive:
        return drive


class HalfWidth:
    """An envelope that halves every width and says so."""

    def apply(self, drive: Drive) -> Drive:
        return drive.with_clamp("envelope", pulse_width_s=drive.pulse_width_s / 2)


@pytest.fixture
def emu():
    host_machine.reset()
    events: list[dict] = []
    e = ControllerEmulator(on_change=events.append, assume_cold=True).start()
    e.events = events  # type: ignore[attr-defined]
    yield e
    e.stop()
    host_machine.reset()



def test_apply_round_trip(emu):
    # The transport alone: no planning, no envelope.
    with SerialOutput(emu.device, envelope=Identity()) as out:
        assert out.connected
        sent = out.apply([Drive(120.0, 300e-6), Drive(250.0, 150e-6, 0.5)])
        assert [(d.pulse_frequency_hz, d.pulse_width_s) for d in sent] == [(120.0, 300e-6), (250.0, 150e-6)]
        status = out.status()
        assert status.channels[0] == P.ChannelStatus(True, 120.0, 300e-6, 1.0)
        assert status.channels[1].frequency_hz == 250.0
        assert status.channels[1].amplitude == pytest.approx(0.5, abs=1e-4)
        # the gate pin pulses, busy-waited to at least the width asked
        deadline = time.monotonic() + 20.0  # a bound only
        while time.monotonic() < deadline and "last_pulse_s" not in host_machine.pin_state(fw.CHANNEL_PINS[1]):
            time.sleep(0.01)
        assert host_machine.pin_state(fw.CHANNEL_PINS[1])["last_pulse_s"] >= 150e-6
    # leaving the block stopped the controller
    assert [e["reason"] for e in emu.events if not e["on"]] == ["stop", "stop"]


def test_fewer_drives_than_channels_turn_the_rest_off(emu):
    with SerialOutput(emu.device) as out:
        out.apply([Drive(100.0, 3e-4), Drive(100.0, 3e-4)])
        out.apply([Drive(150.0, 3e-4)])
        status = out.status()
        assert status.channels[0].frequency_hz == 150.0
        assert not status.channels[1].on


def test_every_drive_passes_the_envelope(emu):
    with SerialOutput(emu.device, envelope=HalfWidth()) as out:
        sent = out.apply([Drive(100.0, 800e-6)])
        assert sent[0].pulse_width_s == pytest.approx(400e-6)
        assert "envelope" in sent[0].clamped
        assert out.status().channels[0].pulse_width_s == pytest.approx(400e-6)


def test_the_default_envelope_is_the_wire_models(emu):
    from tactilize.actuators.sma import SafetyEnvelope, WireController

    with SerialOutput(emu.device) as out:
        assert isinstance(out.envelope, SafetyEnvelope)
        sent = out.apply([Drive(250.0, 1e-3), Drive(100.0, 3e-4, 1.0, (), 0.5)])  # 25 % duty would overheat the wire
        # placed at the top of the felt band, within the envelope, switch fully on
        assert sent[0].clamped == ("band",) and sent[0].amplitude == 1.0
        assert out.envelope.allows(sent[0]) and out.envelope.allows(sent[1])
        planner = WireController(out.envelope.spec, out.envelope.circuit, out.envelope, closed_loop=False)
        power = out.envelope.circuit.power_at(out.envelope.spec.resistance_martensite_ohm)
        assert sent[0].pulse_width_s * power == pytest.approx(planner.band_j(250.0)[1], rel=1e-9)
        lo, hi = planner.band_j(100.0)
        assert sent[1].pulse_width_s * power == pytest.approx(math.sqrt(lo * hi), rel=1e-9)
        assert out.status().channels[0].pulse_width_s == pytest.approx(sent[0].pulse_width_s, abs=1e-9)


def test_controller_limits_clamp_what_the_envelope_lets_through(emu):
    with SerialOutput(emu.device, envelope=Identity()) as out:
        sent = out.apply([Drive(1.0, 20e-3)])  # above the controller's 5 ms
        assert "controller:max_pulse_width_s" in sent[0].clamped
        assert out.status().channels[0].on  # accepted, not refused


def test_a_refusal_is_a_clear_error(emu, monkeypatch):
    with SerialOutput(emu.device, envelope=Identity()) as out:
        # the firmware's limit tightens after the host learnt it: the host's
        # clamp lets 250 Hz through and the controller must refuse it
        monkeypatch.setattr(fw, "MAX_FREQUENCY_MHZ", 200_000)
        with pytest.raises(OutputError, match="refused SET: refused limit \\(frequency\\)"):
            out.apply([Drive(250.0, 1e-4)])
        assert not out.status().channels[0].on


def test_heartbeats_keep_the_drive_alive(emu):
    with SerialOutput(emu.device) as out:
        out.apply([Drive(120.0, 400e-6)])
        time.sleep(0.8)
        assert not [e for e in emu.events if not e["on"]]
        assert out.status().channels[0].on


def test_a_stalled_host_gets_its_drives_back(emu, monkeypatch):
    with SerialOutput(emu.device) as out:
        out.apply([Drive(120.0, 400e-6)])
        beat = out._heartbeat
        monkeypatch.setattr(out, "_heartbeat", lambda: None)  # the host stalls
        assert wait_for(lambda: any(e.get("reason") == "watchdog" for e in emu.events))
        monkeypatch.setattr(out, "_heartbeat", beat)
        # the next heartbeat's ACK carries the watchdog flag; the host re-applies
        assert wait_for(lambda: sum(1 for e in emu.events if e["on"]) == 2)
        assert any(kind == "watchdog" for _, kind, _ in out.events)
        assert out.status().channels[0].on


def test_port_that_cannot_be_opened(tmp_path):
    with pytest.raises(OutputError) as err:
        SerialOutput(str(tmp_path / "no-such-tty"))
    assert isinstance(err.value, TactilizeError)
    assert "no-such-tty" in str(err.value) and "cannot open" in str(err.value)
    with pytest.raises(OutputError, match="cannot open"):
        SerialOutput("/dev/null")


def test_a_port_where_nobody_answers():
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        t0 = time.monotonic()
        with pytest.raises(OutputError, match="no tactile controller answers"):
            SerialOutput(os.ttyname(slave), connect_timeout_s=0.4)
        # it gave up (a bound against hanging, not a timing: a loaded machine is slow)
        assert time.monotonic() - t0 < 30.0
    finally:
        os.close(master)
        os.close(slave)


class FlakyController(threading.Thread):
    """A hand-written controller on a pty that ignores the first SET it sees,
    to show that the host resends when an ACK does not come."""

    def __init__(self):
        super().__init__(daemon=True)
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.device = os.ttyname(self.slave)
        self.sets: list[tuple[int, int]] = []
        self.running = True

    def status(self) -> bytes:
        off = P.ChannelStatus(False, 0.0, 0.0, 0.0)
        return P.encode_status(
            P.ControllerStatus(1, False, 0.0, 0, 0, (off, off), 1.0, 300.0, 1e-5, 5e-3, 0.2, 0.2)
        )

    def run(self):
        dec = P.FrameDecoder()
        while self.running:
            if not select.select([self.master], [], [], 0.02)[0]:
                continue
            for f in dec.feed(os.read(self.master, 1024)):
                if f.command == P.Command.STATUS:
                    os.write(self.master, P.encode_frame(f.seq, P.Command.STATUS_REPLY, self.status()))
                elif f.command == P.Command.SET:
                    self.sets.append((f.seq, P.decode_set_channel(f.payload).channel))
                    if len(self.sets) > 1:
                        os.write(self.master, P.encode_frame(f.seq, P.Command.ACK, bytes((f.command, 0))))
                else:
                    os.write(self.master, P.encode_frame(f.seq, P.Command.ACK, bytes((f.command, 0))))

    def close(self):
        self.running = False
        self.join(1.0)
        os.close(self.master)
        os.close(self.slave)


def test_a_lost_ack_is_resent():
    ctl = FlakyController()
    ctl.start()
    try:
        # The timeout is what is tested, so it must pass once; half a second
        # keeps the ACKs that do come inside it on a loaded machine.
        with SerialOutput(ctl.device, ack_timeout_s=0.5) as out:
            out.apply([Drive(100.0, 3e-4), Drive.off()])
            chans = [ch for _, ch in ctl.sets]
            # both SETs go out back to back, before any reply; channel 0's is
            # ignored and resent under a fresh sequence number (channel 1's only
            # if its ACK was late: resending is harmless)
            assert chans[:2] == [0, 1]
            assert 0 in chans[2:]
            assert len({seq for seq, _ in ctl.sets}) == len(ctl.sets)
    finally:
        ctl.close()


# ------------------------------------------------------------ the port vanishing and returning


class EmulatorProcess:
    """``tactilize controller-emulator`` in a subprocess, its JSON lines collected."""

    def __init__(self, link: str):
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tactilize.cli", "controller-emulator", "--link", link],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        ready, _, _ = select.select([self.proc.stdout], [], [], 20.0)
        assert ready, "emulator did not print its device path"
        self.device = self.proc.stdout.readline().strip()
        self.lines: list[dict] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(json.loads(line))

    def kill(self, sig=signal.SIGKILL):
        self.proc.send_signal(sig)
        self.proc.wait(5.0)
        self._reader.join(2.0)


def test_port_vanishes_and_returns(tmp_path):
    link = str(tmp_path / "ttyTACTILE")
    first = EmulatorProcess(link)
    assert first.device == link
    seen: list[str] = []
    try:
        out = SerialOutput(link, on_event=lambda kind, detail: seen.append(kind))
        out.apply([Drive(120.0, 400e-6), Drive(80.0, 300e-6)])
        assert wait_for(lambda: len(first.lines) == 2)
        first.kill()  # the board is unplugged (or crashed): no goodbye
        # The flag drops first, then the event is told: wait for both.
        assert wait_for(lambda: not out.connected and "lost" in seen)
        with pytest.raises(OutputError, match="disconnected"):
            out.apply([Drive(120.0, 400e-6), Drive(80.0, 300e-6)])
        second = EmulatorProcess(link)  # plugged back in: same path, fresh firmware
        try:
            assert out.wait_connected(5.0)
            # The flag rises first, then the count and the event: wait for them too.
            assert wait_for(lambda: out.reconnects == 1 and "reconnected" in seen)
            # the fresh controller was given the drives again without being asked
            assert wait_for(lambda: len(second.lines) >= 2)
            on = {e["channel"]: e for e in second.lines if e["on"]}
            assert on[0]["frequency_hz"] == 120.0 and on[1]["frequency_hz"] == 80.0
            assert out.status().channels[1].pulse_width_s == pytest.approx(300e-6)
            out.close()
            assert wait_for(lambda: any(e.get("reason") == "stop" for e in second.lines))
        finally:
            second.kill(signal.SIGTERM)
        assert second.proc.returncode == 0
        assert not os.path.lexists(link)  # a clean exit removes its link
    finally:
        if first.proc.poll() is None:
            first.kill()


# ------------------------------------------------------------ the factory


def test_open_output_specs(emu):
    out = open_output(f"serial:{emu.device}")
    try:
        assert isinstance(out, SerialOutput) and out.connected
    finally:
        out.close()
    sim = open_output("simulated")
    try:
        sent = sim.apply([Drive(120.0, 400e-6)])
        assert len(sent) == 2 and sent[1].is_off
    finally:
        sim.close()
    with pytest.raises(OutputError, match="give the port"):
        open_output("serial:")
    with pytest.raises(OutputError, match="unknown output"):
        open_output("carrier-pigeon")


def test_limits_class_is_an_envelope():
    # ActuatorLimits has the envelope contract (apply(Drive) -> Drive), which the
    # serial output relies on for its fallback and for the controller's limits.
    d = ActuatorLimits().apply(Drive(1000.0, 1e-3))
    assert d.pulse_frequency_hz == 300.0 and d.clamped


# ------------------------------------------------------------ the self-sensing loop


def test_the_host_closes_the_loop_on_the_boards_measurements(emu):
    from tactilize.firmware import tactile_wire as W

    from tactilize.actuators.sma import WireSpec
    from tactilize.actuators.sma.controller import SETPOINT_MARTENSITE

    # A wire sitting at the controller's setpoint: the loop then keeps a bias (a
    # hotter wire would rightly have its bias cut to 0, and when is a race).
    r_wire, amps = WireSpec().resistance_at(SETPOINT_MARTENSITE), 0.48
    host_machine.ADC.sources[fw.SENSE_ADC_PINS[0]] = amps / W.DEFAULT_AMPS_PER_COUNT
    host_machine.ADC.sources[fw.RAIL_ADC_PIN] = amps * (r_wire + W.DEFAULT_PATH_OHM[0]) / W.RAIL_VOLTS_PER_COUNT
    with SerialOutput(emu.device) as out:
        assert out.loop is not None
        out.apply([Drive(80.0, 3e-4, 1.0, (), 0.5), Drive.off()])
        ctrl = out.loop.controllers[0]
        assert wait_for(lambda: ctrl.resistance_ohm == pytest.approx(r_wire, abs=0.01), 3.0)
        # the heat it measures is the board's I^2 R, not the nominal circuit's
        assert ctrl.on_power_w == pytest.approx(amps * amps * r_wire, rel=0.02)
        # and the board holds what the host's controller decided
        hold = emu.controller.channels[0].hold
        assert wait_for(lambda: hold.active, 2.0)
        assert hold.bias_w > 0 and hold.target_ohm >= 0
        # within the board's own energy limits (the host leaves the bias that room)
        assert emu.controller.limits.heat_allowed(80.0, hold.energy_j, hold.bias_w)
        report = out.loop.report
        assert report is not None and report.channels[0].count > 0


def test_open_loop_serial_output_sends_no_holds(emu):
    with SerialOutput(emu.device, closed_loop=False) as out:
        assert out.loop is None
        out.apply([Drive(80.0, 3e-4)])
        time.sleep(0.2)
        assert not emu.controller.channels[0].hold.active


def test_a_faulty_sense_path_is_shown_by_the_host(emu):
    """The board (protocol 3) flags a sense amplifier reading 40 % of the current:
    the host keeps which channel and says so in ``fault`` and a ``sense-fault`` event."""
    from tactilize.actuators.sma import Circuit, WireSpec
    from tactilize.firmware import tactile_wire as W

    i = Circuit.resolve("aa-resistor", WireSpec.resolve(None)).current_at(0.6)
    host_machine.ADC.sources[fw.SENSE_ADC_PINS[0]] = 0.4 * i / W.DEFAULT_AMPS_PER_COUNT
    host_machine.ADC.sources[fw.RAIL_ADC_PIN] = i * (0.6 + W.DEFAULT_PATH_OHM[0]) / W.RAIL_VOLTS_PER_COUNT
    with SerialOutput(emu.device) as out:
        assert out.controller_status.version == P.PROTOCOL_VERSION
        assert out.fault is None and out.sense_faults == (False, False)
        out.apply([Drive(60.0, 300e-6), Drive.off()])
        assert wait_for(lambda: out.sense_faults == (True, False))
        assert "channel 0" in out.fault
        assert any(kind == "sense-fault" for _, kind, _ in out.events)
        assert out.loop.report is not None and out.loop.report.faults == (True, False)


def test_a_firmware_error_on_the_board_is_shown_by_the_host(emu, monkeypatch):
    """An exception inside the firmware turns the board's outputs off and flags
    every reply after it: the host says so in ``fault`` and a ``firmware-error`` event."""
    ch = emu.controller.channels[0]

    def broken(*args, **kwargs):
        raise MemoryError("out of heap")

    with SerialOutput(emu.device) as out:
        assert not out.firmware_error and out.fault is None
        monkeypatch.setattr(ch, "set", broken)
        with pytest.raises(OutputError):
            out.apply([Drive(60.0, 300e-6), Drive.off()])  # no ACK for the frame that failed
        assert wait_for(lambda: out.firmware_error)
        assert "firmware" in out.fault
        assert any(kind == "firmware-error" for _, kind, _ in out.events)
        assert emu.controller.errors >= 1 and not ch.on


def test_a_version_2_sense_reply_still_decodes():
    import struct

    v2 = struct.pack(P.SENSE_FORMAT_V2, 2500, 600000, 480000, 0, 300000, 3, 0, 0, 0, 0, 0)
    report = P.decode_sense(v2)
    assert report.faults is None and report.channels[0].resistance_ohm == pytest.approx(0.6)
    v3 = struct.pack(P.SENSE_FORMAT, 2500, 600000, 480000, 0, 300000, 3, 0, 0, 0, 0, 0, 0b10)
    assert P.decode_sense(v3).faults == (False, True)
