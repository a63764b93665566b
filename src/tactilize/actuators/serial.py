"""The serial output: drives sent as frames to the tactile controller.

:class:`SerialOutput` opens a serial port (a Pico's ``/dev/ttyACM0``, or the
pseudo-terminal of ``tactilize controller-emulator``), checks that a controller
answers, and then keeps it alive:

- :meth:`~SerialOutput.apply` places each drive's pulse heat in the wire's felt
  band (the host side of :class:`~tactilize.actuators.sma.WireController`, open
  loop: the board's own loop on the measured resistance is the firmware's job),
  passes it through the safety envelope of the configured wire and circuit and
  the controller's own hard limits (learnt from its STATUS reply),
  sends one SET frame per channel and waits for each ACK, resending on a timeout
  or a checksum NAK;
- a keeper thread sends a HEARTBEAT every ``heartbeat_interval_s`` (50 ms) so the
  controller's 200 ms watchdog never fires while the host is alive;
- when the port vanishes (USB unplugged, emulator gone) the controller's
  watchdog has turned the outputs off; the host notes it (:attr:`events`),
  polls the path until it can be reopened, and re-applies the current drives.
  It does the same when a heartbeat ACK says the watchdog fired anyway (a host
  stalled for more than 200 ms).
- a version 3 board flags a faulty sense path (its wire then limited with the
  circuit's worst case): :attr:`~SerialOutput.sense_faults` (None from version 2),
  :attr:`~SerialOutput.fault`, a ``sense-fault`` event; the loop skips the reading.

Threads: a reader (decodes replies, matches them to requests by sequence
number) and a keeper (heartbeats, reconnection).  Callers' threads only write
frames and wait for replies.
"""

from __future__ import annotations

import collections
import errno
import itertools
import os
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

from ..errors import OutputError
from ..drive import Drive
from ..mapping import ActuatorLimits
from . import frames as P
from .base import OutputBase
from .sensed import SensedLoop, fault_text
from .sma import Circuit, SafetyEnvelope, WireController, WireSpec, default_envelope

__all__ = ["SerialOutput"]


class _PortLost(Exception):
    """The port failed under us (internal; callers see OutputError)."""


@dataclass
class _Waiter:
    event: threading.Event = field(default_factory=threading.Event)
    reply: P.Frame | None = None
    lost: bool = False


class SerialOutput(OutputBase):
    """Drives on a tactile controller over a serial port.

    Parameters
    ----------
    port : str
        Serial device path (``/dev/ttyACM0``, ``COM3``, a pty path).
    wire, circuit : optional
        The wire and the driver circuit on the board (the paper's 75 um on
        ``aa-resistor`` by default, see docs/hardware.md).
    envelope : object with ``apply(Drive) -> Drive``, optional
        Safety envelope applied to every drive before it is sent; default: the
        :class:`~tactilize.actuators.sma.SafetyEnvelope` of the wire and circuit.
        With an SMA envelope each pulse's width is first planned in the felt band.
    baudrate : int
        Ignored by USB CDC and ptys; matters for a UART bridge.
    ack_timeout_s : float
        How long to wait for each ACK before resending [s].
    retries : int
        Resends after the first attempt.
    heartbeat_interval_s : float
        Heartbeat period [s]; must stay well under the controller's 200 ms watchdog.
    reconnect_interval_s : float
        How often a vanished port is tried again [s].
    connect_timeout_s : float
        How long the first connection may take to get a STATUS reply [s].
    unresponsive_s : float
        A connected controller silent for this long is treated as lost [s].
    on_event : callable, optional
        ``on_event(kind, detail)`` for ``connected``, ``lost``, ``reconnected``,
        ``watchdog``, ``reapply-failed``, ``hold-refused``, ``sense-fault`` and ``sense-ok``
        events (called from a worker thread).
    closed_loop : bool
        Ask the board for its self-sensing measurements with every heartbeat,
        close the :class:`WireController` loop on them and send the heat it
        decides as HOLD frames (:mod:`tactilize.actuators.sensed`).

    Raises
    ------
    OutputError
        The port cannot be opened, or no controller answers on it.
    """

    #: amplitude is felt strength, placed in the wire's felt band; the amplitude
    #: sent to the board is the fraction of each pulse its switch conducts
    amplitude_is_intensity = False

    channels = 2

    def __init__(
        self,
        port: str,
        *,
        envelope: Any = None,
        wire: WireSpec | str | None = None,
        circuit: Circuit | str | None = None,
        baudrate: int = 115200,
        ack_timeout_s: float = 0.1,
        retries: int = 3,
        heartbeat_interval_s: float = 0.05,
        reconnect_interval_s: float = 0.1,
        connect_timeout_s: float = 2.0,
        unresponsive_s: float = 0.5,
        on_event: Callable[[str, str], None] | None = None,
        closed_loop: bool = True,
    ) -> None:
        self.port = str(port)
        spec = WireSpec.resolve(wire)
        self.envelope = envelope if envelope is not None else (
            default_envelope() if wire is None and circuit is None else SafetyEnvelope(spec, Circuit.resolve(circuit, spec))
        )
        self._planner = (
            WireController(self.envelope.spec, self.envelope.circuit, self.envelope, closed_loop=False)
            if isinstance(self.envelope, SafetyEnvelope)
            else None
        )
        #: the self-sensing loop (:class:`~tactilize.actuators.sensed.SensedLoop`), when closed
        self.loop = SensedLoop(self.envelope) if closed_loop and isinstance(self.envelope, SafetyEnvelope) else None
        self.baudrate = baudrate
        self.ack_timeout_s = ack_timeout_s
        self.retries = retries
        self.heartbeat_interval_s = heartbeat_interval_s
        self.reconnect_interval_s = reconnect_interval_s
        self.unresponsive_s = unresponsive_s
        self._on_event = on_event
        #: recent ``(monotonic time [s], kind, detail)`` events
        self.events: collections.deque = collections.deque(maxlen=256)
        #: times the connection was re-established after a loss
        self.reconnects = 0
        #: the controller's last STATUS reply (limits, firmware version)
        self.controller_status: P.ControllerStatus | None = None
        #: per channel, whether the board flags its sense path faulty; None while
        #: unknown (a version 2 board cannot say)
        self.sense_faults: tuple[bool, ...] | None = None

        self._seq = itertools.count(1)
        self._write_lock = threading.RLock()
        self._pending: dict[int, _Waiter] = {}
        self._pending_lock = threading.Lock()
        self._apply_lock = threading.RLock()
        self._serial: Any = None
        self._connected = threading.Event()
        self._closing = threading.Event()
        self._reapply = threading.Event()
        self._desired: list[Drive] = [Drive.off()] * self.channels
        self._controller_limits: ActuatorLimits | None = None
        self._last_rx_s = time.monotonic()
        self._decoder = P.FrameDecoder()

        self._serial = self._open()  # raises OutputError with the reason
        self._reader = threading.Thread(target=self._read_loop, name=f"serial-reader {self.port}", daemon=True)
        self._reader.start()
        try:
            self._handshake(deadline_s=time.monotonic() + connect_timeout_s)
        except OutputError:
            self._shutdown()
            raise
        self._connected.set()
        self._event("connected", self.port)
        self._keeper = threading.Thread(target=self._keep_loop, name=f"serial-keeper {self.port}", daemon=True)
        self._keeper.start()

    # ------------------------------------------------------------ public

    @property
    def connected(self) -> bool:
        """True while the controller answers on the port."""
        return self._connected.is_set()

    @property
    def fault(self) -> str | None:
        """One line when the board flags a sense path faulty, else None."""
        return fault_text(self.sense_faults)

    def _sense_faults(self, faults: tuple[bool, ...]) -> None:
        old, self.sense_faults = self.sense_faults, tuple(faults)
        if any(faults) != any(old or ()):
            self._event("sense-fault" if any(faults) else "sense-ok", self.fault or "sense paths read true again")

    def wait_connected(self, timeout_s: float) -> bool:
        """Block until connected (or the timeout [s] passes); True when connected."""
        return self._connected.wait(timeout_s)

    @property
    def drives(self) -> list[Drive]:
        """The drives the controller should be running (re-applied after a reconnect)."""
        return list(self._desired)

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        """Send one drive per channel; return the drives as sent (after the envelope).

        Raises
        ------
        OutputError
            The controller refused a drive, did not acknowledge it, or is
            disconnected (the drives are kept and sent when it returns).
        """
        drives = [self._make_safe(d) for d in self._check(channels)]
        with self._apply_lock:
            self._desired = drives
            self._send_drives(drives)
            if self.loop is not None:
                self.loop.command(drives, time.monotonic())
                self._send_holds()
        return drives

    def stop(self) -> None:
        """Turn every channel off.

        When the controller is disconnected its watchdog has already turned
        everything off, so this only forgets the drives.

        Raises
        ------
        OutputError
            The controller is connected but did not acknowledge the stop.
        """
        with self._apply_lock:
            self._desired = [Drive.off()] * self.channels
            if self.loop is not None:
                self.loop.stop()
            if not self.connected:
                return
            try:
                self._request(P.Command.STOP)
            except _PortLost:
                return

    def status(self) -> P.ControllerStatus:
        """Ask the controller what it is doing (channels, hard limits, counters)."""
        try:
            reply = self._request(P.Command.STATUS)
        except _PortLost:
            raise OutputError(self.port, "controller disconnected") from None
        status = P.decode_status(reply.payload)
        self.controller_status = status
        return status

    def close(self) -> None:
        """Stop the outputs, end the threads and close the port."""
        if self._closing.is_set():
            return
        try:
            self.stop()
        except OutputError:
            pass  # closing anyway: the controller's watchdog turns it off
        finally:
            self._shutdown()

    # ------------------------------------------------------------ drives

    def _make_safe(self, drive: Drive) -> Drive:
        if drive.is_off:
            return Drive.off(drive.clamped)
        if self._planner is not None:
            plan = self._planner.plan(drive)
            clamped = drive.clamped + tuple(n for n in plan.clamped if n not in drive.clamped)
            drive = drive.replace(pulse_width_s=plan.pulse_width_s, amplitude=plan.level, clamped=clamped)
        safe = self.envelope.apply(drive)
        limits = self._controller_limits
        if limits is not None and not safe.is_off:
            clamped = limits.apply(safe.replace(clamped=()))
            if clamped.clamped:
                # Name the controller's limits apart from the envelope's.
                names = safe.clamped + tuple(f"controller:{n}" for n in clamped.clamped)
                safe = clamped.replace(clamped=names)
        return safe

    def _send_drives(self, drives: Sequence[Drive]) -> None:
        requests = []
        for index, d in enumerate(drives):
            if d.is_off:
                payload = P.encode_set_channel(index, 0.0, 0.0, 0.0)
            else:
                payload = P.encode_set_channel(index, d.pulse_frequency_hz, d.pulse_width_s, d.amplitude, d.regularity)
            requests.append((int(P.Command.SET), payload))
        try:
            self._transact(requests)
        except _PortLost:
            raise OutputError(
                self.port, "controller disconnected; outputs are off and the drives will be re-applied when it returns"
            ) from None

    def _send_holds(self) -> None:
        """The loop's HOLD frames whose heat moved (the apply lock is held)."""
        holds = self.loop.holds(time.monotonic()) if self.loop is not None else []
        requests = [(int(P.Command.HOLD), P.encode_hold(*h)) for h in holds]
        if requests:
            try:
                self._transact(requests)
            except _PortLost:
                self.loop.forget()

    # ------------------------------------------------------------ requests

    def _request(self, command: int, payload: bytes = b"", *, attempts: int | None = None) -> P.Frame:
        """One request and its reply (see :meth:`_transact`)."""
        return self._transact([(int(command), payload)], attempts=attempts)[0]

    def _transact(self, requests: Sequence[tuple[int, bytes]], *, attempts: int | None = None) -> list[P.Frame]:
        """Send frames back to back and wait for every reply (pipelined: one
        round trip for all channels, not one each).  Frames whose reply times out
        or is a checksum NAK are resent, each with a fresh sequence number.

        Raises OutputError on a refusal or no answer after ``attempts`` tries,
        _PortLost when the port is gone.  Commands are idempotent, so a frame
        applied but whose ACK was lost is harmless to resend.
        """
        attempts = self.retries + 1 if attempts is None else attempts
        replies: list[P.Frame | None] = [None] * len(requests)
        todo = list(range(len(requests)))
        for _ in range(attempts):
            waiting: dict[int, tuple[int, _Waiter]] = {}
            try:
                for i in todo:
                    seq = next(self._seq) & 0xFF
                    waiter = _Waiter()
                    with self._pending_lock:
                        self._pending[seq] = waiter
                    waiting[i] = (seq, waiter)
                    self._write(P.encode_frame(seq, requests[i][0], requests[i][1]))
                deadline = time.monotonic() + self.ack_timeout_s
                for _, waiter in waiting.values():
                    waiter.event.wait(max(0.0, deadline - time.monotonic()))
            finally:
                with self._pending_lock:
                    for seq, _ in waiting.values():
                        self._pending.pop(seq, None)
            if any(w.lost for _, w in waiting.values()):
                raise _PortLost()
            retry = []
            for i, (_, waiter) in waiting.items():
                reply = waiter.reply
                if reply is None:
                    retry.append(i)
                    continue
                if reply.command == P.Command.NAK:
                    reason, detail = P.decode_nak(reply.payload)
                    if reason == P.NakReason.BAD_CHECKSUM:
                        retry.append(i)  # corrupted on the wire: send again
                        continue
                    what = getattr(reason, "name", str(reason)).lower().replace("_", " ")
                    extra = f" ({detail.name.lower().replace('_', ' ')})" if getattr(detail, "value", 0) else ""
                    raise OutputError(self.port, f"controller refused {P.command_name(requests[i][0])}: {what}{extra}")
                replies[i] = reply
            todo = retry
            if not todo:
                return replies  # type: ignore[return-value]
        names = ", ".join(sorted({P.command_name(requests[i][0]) for i in todo}))
        raise OutputError(self.port, f"controller did not acknowledge {names} after {attempts} attempts")

    def _write(self, frame: bytes) -> None:
        with self._write_lock:
            ser = self._serial
            if ser is None:
                raise _PortLost()
            try:
                ser.write(frame)
            except Exception as exc:  # pyserial raises SerialException, OSError or TypeError on a dead fd
                self._lost(ser, f"write failed ({exc})")
                raise _PortLost() from None

    # ------------------------------------------------------------ port

    def _open(self) -> Any:
        import serial  # pyserial; imported here so the protocol stays importable without it

        try:
            ser = serial.Serial(self.port, self.baudrate, timeout=0.02, write_timeout=0.5, exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            code = getattr(exc, "errno", None)
            reason = os.strerror(code) if isinstance(code, int) else str(exc)
            if code == errno.ENOTTY:
                reason = f"not a serial port: {reason}"
            raise OutputError(self.port, f"cannot open serial port ({reason})") from None
        try:
            ser.reset_input_buffer()
        except Exception:
            pass
        return ser

    def _handshake(self, deadline_s: float) -> None:
        """Ask for STATUS until it answers (a board may still be booting)."""
        last: OutputError | None = None
        while True:
            try:
                status = P.decode_status(self._request(P.Command.STATUS, attempts=1).payload)
                break
            except _PortLost:
                raise OutputError(self.port, "serial port closed during the handshake") from None
            except OutputError as exc:
                last = exc
            if time.monotonic() >= deadline_s:
                raise OutputError(
                    self.port, "no tactile controller answers (is the controller firmware running on it?)"
                ) from last
        self.controller_status = status
        if status.version >= 3:
            self._sense_faults((status.sense_fault,) * self.channels)
        # Frequency and width limits are exact in wire units (a clamped value
        # encodes to the limit itself); the duty is a product of two rounded
        # integers, so it stays 10 ppm inside to survive the rounding.
        self._controller_limits = ActuatorLimits(
            name="controller",
            min_frequency_hz=status.min_frequency_hz,
            max_frequency_hz=status.max_frequency_hz,
            min_pulse_width_s=status.min_pulse_width_s,
            max_pulse_width_s=status.max_pulse_width_s,
            max_duty_ratio=status.max_duty_ratio * (1 - 1e-5),
        )

    def _lost(self, ser: Any, reason: str) -> None:
        with self._write_lock:
            if self._serial is not ser or ser is None:
                return
            self._serial = None
            was_connected = self._connected.is_set()
            self._connected.clear()
            try:
                ser.close()
            except Exception:
                pass
        with self._pending_lock:
            for waiter in self._pending.values():
                waiter.lost = True
                waiter.event.set()
        if was_connected and not self._closing.is_set():
            self._event("lost", f"{reason}; the controller's watchdog turns its outputs off")

    def _shutdown(self) -> None:
        self._closing.set()
        with self._write_lock:
            ser, self._serial = self._serial, None
            self._connected.clear()
        if ser is not None:
            try:
                ser.close()
            except Exception:
                pass
        for name in ("_keeper", "_reader"):
            t = getattr(self, name, None)
            if t is not None and t is not threading.current_thread():
                t.join(timeout=1.0)

    def _event(self, kind: str, detail: str) -> None:
        self.events.append((time.monotonic(), kind, detail))
        if self._on_event is not None:
            try:
                self._on_event(kind, detail)
            except Exception:
                pass  # a faulty observer must not stop the heartbeat

    # ------------------------------------------------------------ threads

    def _read_loop(self) -> None:
        while not self._closing.is_set():
            ser = self._serial
            if ser is None:
                time.sleep(0.01)
                continue
            try:
                data = ser.read(max(1, ser.in_waiting))
            except Exception as exc:  # SerialException / OSError / TypeError once the fd dies
                self._lost(ser, f"read failed ({exc.__class__.__name__})")
                continue
            # A reply takes well under a millisecond on USB; a candidate older
            # than 50 ms was corrupted and must not hold later replies back.
            frames = self._decoder.feed(data) if data else []
            frames += self._decoder.expire_stale(0.05)
            for frame in frames:
                self._dispatch(frame)

    def _dispatch(self, frame: P.Frame) -> None:
        self._last_rx_s = time.monotonic()
        if frame.command == P.Command.ACK and len(frame.payload) >= 2 and frame.payload[1] & P.FLAG_WATCHDOG_TRIPPED:
            # The controller turned its outputs off although we are alive
            # (the host stalled); put the drives back.
            if any(not d.is_off for d in self._desired):
                self._reapply.set()
        version = self.controller_status.version if self.controller_status is not None else 0
        if frame.command == P.Command.ACK and len(frame.payload) >= 2 and version >= 3:
            flagged = bool(frame.payload[1] & P.FLAG_SENSE_FAULT)
            if flagged != any(self.sense_faults or ()):
                self._sense_faults((flagged,) * self.channels)  # which channel: the SENSE reply says
        if frame.command == P.Command.SENSE_REPLY:
            try:
                report = P.decode_sense(frame.payload)
            except Exception:  # struct.error: a reply of another firmware version
                report = None
            if report is not None and report.faults is not None:
                self._sense_faults(report.faults)
            if report is not None and self.loop is not None:
                self.loop.observe(report, time.monotonic())
        with self._pending_lock:
            waiter = self._pending.get(frame.seq)
        if waiter is not None:
            waiter.reply = frame
            waiter.event.set()

    def _keep_loop(self) -> None:
        while not self._closing.wait(self.heartbeat_interval_s):
            if self._connected.is_set():
                self._heartbeat()
            else:
                self._reconnect()

    def _heartbeat(self) -> None:
        ser = self._serial
        if time.monotonic() - self._last_rx_s > self.unresponsive_s:
            self._lost(ser, f"controller silent for more than {self.unresponsive_s:g} s")
            return
        seq = next(self._seq) & 0xFF
        version = self.controller_status.version if self.controller_status is not None else 0
        try:
            # Not waited for: any reply refreshes _last_rx_s, and a stalled
            # controller is caught by the silence check above.
            self._write(P.encode_frame(seq, P.Command.HEARTBEAT))
            if self.loop is not None or version >= 3:
                ask = P.SENSE_V3 if version >= 3 else b""  # a version 2 board knows only the empty SENSE
                self._write(P.encode_frame(next(self._seq) & 0xFF, P.Command.SENSE, ask))
        except _PortLost:
            return
        if self.loop is not None:
            with self._apply_lock:
                try:
                    self._send_holds()
                except OutputError as exc:
                    self._event("hold-refused", exc.fault)
        if self._reapply.is_set():
            self._reapply.clear()
            self._event("watchdog", "controller watchdog fired while connected; re-applying drives")
            self._reapply_drives()

    def _reconnect(self) -> None:
        if self._serial is None:
            try:
                ser = self._open()
            except OutputError:
                time.sleep(self.reconnect_interval_s)
                return
            self._decoder = P.FrameDecoder()
            with self._write_lock:
                self._serial = ser
        try:
            self._handshake(deadline_s=time.monotonic())
        except OutputError:
            # The path exists but nothing answers yet (a board booting): try again.
            self._lost_quietly()
            time.sleep(self.reconnect_interval_s)
            return
        self._last_rx_s = time.monotonic()
        # Drives first, then "connected": whoever waits for the connection
        # finds the controller already running them.
        self._reapply_drives()
        self._connected.set()
        self.reconnects += 1
        self._event("reconnected", self.port)

    def _lost_quietly(self) -> None:
        with self._write_lock:
            ser, self._serial = self._serial, None
        if ser is not None:
            try:
                ser.close()
            except Exception:
                pass

    def _reapply_drives(self) -> None:
        if self.loop is not None:
            self.loop.forget()
        with self._apply_lock:
            drives = [self._make_safe(d) for d in self._desired]
            try:
                self._send_drives(drives)
            except OutputError as exc:
                self._event("reapply-failed", exc.fault)
