"""The command line against the emulated controller: `controller-emulator` and
`drive --output serial:PATH --hold S`."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
import tty

import numpy as np
import pytest
from PIL import Image

from tactilize.actuators import frames as P
from _waiting import wait_for


def cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "tactilize.cli", *args]


class Emulator:
    def __init__(self, *args: str):
        self.proc = subprocess.Popen(
            cli("controller-emulator", *args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        ready, _, _ = select.select([self.proc.stdout], [], [], 20.0)
        assert ready, "no device path printed"
        self.device = self.proc.stdout.readline().strip()
        self.lines: list[dict] = []
        self._t = threading.Thread(target=self._read, daemon=True)
        self._t.start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(json.loads(line))

    def stop(self, sig=signal.SIGTERM) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        rc = self.proc.wait(5.0)
        self._t.join(2.0)
        return rc


@pytest.fixture
def emulator():
    e = Emulator()
    yield e
    e.stop()


@pytest.fixture
def grating(tmp_path):
    x = np.arange(256)
    img = (127 + 100 * np.sin(2 * np.pi * x / 16))[None, :].repeat(256, 0).astype(np.uint8)
    path = tmp_path / "grating.png"
    Image.fromarray(img).save(path)
    return str(path)



def test_emulator_prints_its_device_then_one_json_line_per_change(emulator):
    assert os.path.exists(emulator.device)
    import serial

    with serial.Serial(emulator.device, timeout=1.0) as ser:
        ser.write(P.encode_frame(1, P.Command.SET, P.encode_set_channel(0, 120.0, 300e-6, 1.0)))
        dec = P.FrameDecoder()
        frames: list[P.Frame] = []
        while not frames:
            chunk = ser.read(1)
            assert chunk, "no ACK"
            frames += dec.feed(chunk)
        assert frames[0].command == P.Command.ACK
        assert wait_for(lambda: len(emulator.lines) >= 2, 2.0)  # on, then the watchdog's off
    on, off = emulator.lines[:2]
    assert {k: on[k] for k in ("channel", "on", "frequency_hz", "pulse_width_us")} == {
        "channel": 0,
        "on": True,
        "frequency_hz": 120.0,
        "pulse_width_us": 300.0,
    }
    assert off["channel"] == 0 and off["on"] is False and off["reason"] == "watchdog"
    assert 0.19 <= off["t_s"] - on["t_s"] <= 0.25


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_emulator_ends_on_a_signal(sig):
    e = Emulator()
    assert e.stop(sig) == 0


def test_drive_holds_on_the_controller_and_exits_0(emulator, grating):
    t0 = time.monotonic()
    res = subprocess.run(
        cli("drive", grating, "--speed", "60", "--output", f"serial:{emulator.device}", "--hold", "0.5"),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert res.returncode == 0, res.stderr
    assert "acknowledged" in res.stdout
    assert time.monotonic() - t0 >= 0.5
    assert wait_for(lambda: sum(1 for e in emulator.lines if e.get("reason") == "stop") == 2)
    ons = [e for e in emulator.lines if e["on"]]
    stops = [e for e in emulator.lines if not e["on"]]
    assert {e["channel"] for e in ons} == {0, 1}
    # held for the time asked, kept alive by heartbeats (no watchdog), then stopped
    assert all(e["reason"] == "stop" for e in stops)
    # held at least as long as asked (a loaded machine may only make it longer)
    held = min(e["t_s"] for e in stops) - max(e["t_s"] for e in ons)
    assert held >= 0.45


def test_drive_json_reports_the_acknowledged_drive(emulator, grating):
    res = subprocess.run(
        cli("drive", grating, "--speed", "30", "--output", f"serial:{emulator.device}", "--hold", "0.1", "--json"),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert res.returncode == 0, res.stderr
    doc = json.loads(res.stdout)
    assert doc["output"]["acknowledged"] is True
    assert doc["output"]["applied"][0]["pulse_frequency_hz"] == pytest.approx(doc["pulse_frequency_hz"], rel=1e-6)
    assert wait_for(lambda: any(e["on"] for e in emulator.lines))
    on = [e for e in emulator.lines if e["on"]][0]
    # the controller runs what the CLI reported (PWM frequency in whole hertz)
    assert on["frequency_hz"] == pytest.approx(doc["output"]["applied"][0]["pulse_frequency_hz"], abs=0.5)


def test_drive_fails_with_one_line_when_the_port_is_missing(tmp_path, grating):
    missing = str(tmp_path / "ttyNOPE")
    res = subprocess.run(
        cli("drive", grating, "--speed", "60", "--output", f"serial:{missing}", "--hold", "0.5"),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert res.returncode != 0
    assert len(res.stderr.strip().splitlines()) == 1
    assert missing in res.stderr and "cannot open" in res.stderr
    assert "Traceback" not in res.stderr


def test_drive_fails_when_no_controller_answers(grating):
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        res = subprocess.run(
            cli("drive", grating, "--speed", "60", "--output", f"serial:{os.ttyname(slave)}", "--hold", "0.1"),
            capture_output=True,
            text=True,
            timeout=60,
        )
    finally:
        os.close(master)
        os.close(slave)
    assert res.returncode != 0
    assert len(res.stderr.strip().splitlines()) == 1 and "no tactile controller answers" in res.stderr


def test_drive_fails_when_the_controller_vanishes_during_the_hold(grating):
    e = Emulator()
    proc = subprocess.Popen(
        cli("drive", grating, "--speed", "60", "--output", f"serial:{e.device}", "--hold", "5"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert wait_for(lambda: any(x["on"] for x in e.lines), 20.0)
        e.stop(signal.SIGKILL)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode != 0
    assert len(err.strip().splitlines()) == 1 and "controller lost" in err


def test_hold_without_output_is_bad_input(grating):
    res = subprocess.run(cli("drive", grating, "--speed", "60", "--hold", "1"), capture_output=True, text=True)
    assert res.returncode == 2 and "--hold" in res.stderr


def test_a_controller_lost_while_the_drive_is_acknowledged_is_a_lost_controller(monkeypatch):
    # Deterministic twin of the test above: the port goes between one channel's
    # ACK and the next, so apply itself fails on a disconnected output.
    from tactilize.actuators import factory
    from tactilize.cli.outputs import hold_drive
    from tactilize.drive import Drive
    from tactilize.errors import OutputError

    class Vanishing:
        channels = 2
        connected = True
        events = ()
        closed = False

        def apply(self, drives):
            self.connected = False
            raise OutputError("/dev/pts/9", "controller disconnected; outputs are off")

        def close(self):
            self.closed = True

    out = Vanishing()
    monkeypatch.setattr(factory, "open_output", lambda spec: out)
    with pytest.raises(OutputError, match=r"controller lost before the hold began") as err:
        hold_drive("serial:/dev/pts/9", Drive(pulse_frequency_hz=50.0, pulse_width_s=0.002), 1.0)
    assert err.value.source == "serial:/dev/pts/9" and out.closed
