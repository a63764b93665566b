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
- a version 4 board plays pulse events (:meth:`~SerialOutput.play`): each
  one a scheduled pulse on the board's clock, which the host keeps in step
  (:attr:`~SerialOutput.clock`, PING/PONG with every heartbeat); the board counts
  what it did with them (:attr:`~SerialOutput.event_counts`).  An older board
  gets the equivalent drives (:attr:`~SerialOutput.schedules_pulses` is False; docs/firmware.md);
- a version 3 board flags a faulty sense path (its wire then limited with the
  circuit's worst case): :attr:`~SerialOutput.sense_faults` (None from version 2),
  :attr:`~SerialOutput.fault`, a ``sense-fault`` event; the loop skips the reading.

Threads (:mod:`tactilize.actuators.serial_link`): a reader (decodes replies,
matches them to requests by sequence number) and a keeper (heartbeats, clock
exchanges, reconnection).  Callers' threads only write
frames and wait for replies.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from typing import TYPE_CHECKING, Any, Callable, Sequence

from ..drive import Drive
from ..errors import OutputError
from . import frames as P
from .base import OutputBase
from .clock_sync import ClockSync
from .sensed import SensedLoop, fault_text
from ..surface.clock import StrokeClock
from .serial_events import EventSender, board_limits, plan_pulses
from .serial_link import PortLost as _PortLost
from .serial_link import SerialLink
from .sma import Circuit, SafetyEnvelope, WireController, WireSpec, default_envelope

if TYPE_CHECKING:
    from ..surface.rendering import Frame

__all__ = ["SerialOutput"]

#: PING exchanges in the handshake with a version 4 board, before any event is sent
SYNC_BURST = 8


class SerialOutput(SerialLink, OutputBase):
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
        SerialLink.__init__(self, port, baudrate=baudrate, ack_timeout_s=ack_timeout_s, retries=retries,
                            on_event=on_event)
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
        self.heartbeat_interval_s = heartbeat_interval_s
        self.reconnect_interval_s = reconnect_interval_s
        self.unresponsive_s = unresponsive_s
        #: times the connection was re-established after a loss
        self.reconnects = 0
        #: the controller's last STATUS reply (limits, firmware version)
        self.controller_status: P.ControllerStatus | None = None
        #: per channel, whether the board flags its sense path faulty; None while
        #: unknown (a version 2 board cannot say)
        self.sense_faults: tuple[bool, ...] | None = None
        #: the board caught an error in its firmware and turned its outputs off
        #: (ACK flag bit 2, until a STOP); the drives are sent again
        self.firmware_error = False

        #: the board's clock as the host knows it (version 4 boards), from PING/PONG
        self.clock = ClockSync()
        #: per channel, the board's counters of scheduled pulses (version 4), from the latest PONG
        self.event_counts: tuple[P.EventCounts, ...] | None = None
        self._pings: dict[int, float] = {}
        self._apply_lock = threading.RLock()
        self._reapply = threading.Event()
        self._desired: list[Drive] = [Drive.off()] * self.channels
        self._events_mode = False
        #: The operating point last played for a frame on a board without scheduled pulses:
        #: (requested Drives, host time [s], as sent).
        self._fallback: tuple[tuple[Drive, ...], float, list[Drive]] = ((), 0.0, [])
        self._sender = EventSender(self.channels)
        self._stroke_clock = StrokeClock()
        self._tokens = itertools.count(1)

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

    # OutputBase's connected and fault are plain attributes; SerialOutput makes them
    # read-only properties (mypy reports the ignores below if that changes).
    @property
    def connected(self) -> bool:
        """True while the controller answers on the port."""
        return self._connected.is_set()

    @property
    def schedules_pulses(self) -> bool:
        """The board plays scheduled pulses (protocol version 4 or later, read from STATUS)."""
        status = self.controller_status
        return status is not None and status.version >= 4

    @property
    def fault(self) -> str | None:
        """One line when the board flags a sense path faulty or a firmware error, else None."""
        if self.firmware_error:
            return "the controller caught an error in its firmware and turned its outputs off"
        return fault_text(self.sense_faults)

    def _sense_faults(self, faults: tuple[bool, ...]) -> None:
        old, self.sense_faults = self.sense_faults, tuple(faults)
        if any(faults) != any(old or ()):
            self._event("sense-fault" if any(faults) else "sense-ok", self.fault or "sense paths read true again")

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
        self._fallback = ((), 0.0, [])
        with self._apply_lock:
            self._desired = drives
            self._events_mode = False
            self._sender.forget()  # a SET replaces the board's schedule
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
        self._fallback = ((), 0.0, [])
        with self._apply_lock:
            self._desired = [Drive.off()] * self.channels
            self._events_mode = False
            self._sender.forget()
            if self.loop is not None:
                self.loop.stop()
            if not self.connected:
                return
            try:
                self._request(P.Command.STOP)
            except _PortLost:
                return

    def play(self, frame: Frame, now_s: float, channels: Sequence[Drive]) -> list[Drive]:
        """Play one rendered frame (the Output interface): a regular train (a steady rendering's)
        as its Drive, with SET (the board's own train); other events as scheduled pulses on a
        board that schedules them (:attr:`schedules_pulses`), else their operating point."""
        if frame.regular:
            return self.apply(channels)
        return self._play_events([frame.events] * self.channels, now_s, channels)

    def _play_events(self, channels: Sequence[Sequence[Any]], now_s: float, equivalent: Sequence[Drive]) -> list[Drive]:
        """Per channel, pulse events from now on, replacing those not yet fired (docs/surfaces.md).

        On a version 4 board each event becomes a scheduled pulse on the board's
        clock (:mod:`tactilize.actuators.serial_events`); the equivalent drives
        keep the operating point (the HOLD loop).  An older board gets the
        equivalent drives through :meth:`apply`.

        Parameters
        ----------
        channels : sequence of sequence of PulseEvent
            Per channel, events with ``t_s`` on the stroke's clock [s].
        now_s : float
            The stroke time that is now [s] (the newest pen sample's).
        equivalent : sequence of Drive
            Per channel, the steady drive of the window.

        Returns
        -------
        list of Drive
            The equivalent drives as the board may play them.

        Raises
        ------
        OutputError
            The controller refused a frame, did not acknowledge it, or is disconnected.
        """
        if not self.schedules_pulses or not self.clock.ready:
            # The operating point alone: the same Drives handed again with new events (the
            # renderer hands a frame whenever its events change) are not sent again for 0.1 s.
            held, at, sent = self._fallback
            host = time.monotonic()
            if (not self._events_mode and len(held) == len(equivalent) and host - at < 0.1
                    and all(a is b for a, b in zip(held, equivalent))):
                return sent
            sent = self.apply(equivalent)
            self._fallback = (tuple(equivalent), host, sent)
            return sent
        drives = [self._make_safe(d) for d in self._check(equivalent)]
        status = self.controller_status
        assert status is not None
        widths = (int(math.ceil(status.min_pulse_width_s * 1e6)), int(status.max_pulse_width_s * 1e6))
        lists = list(channels) + [[] for _ in range(self.channels - len(channels))]
        host_now = time.monotonic()
        zero = self._stroke_clock.host_s(now_s, host_now)
        planned: dict[int, list[tuple[float, int]]] = {}
        with self._apply_lock:
            entering = not self._events_mode
            requests = []
            for index, evs in enumerate(lists):
                if id(evs) not in planned:  # both pins usually get the same list: plan it once
                    planned[id(evs)] = plan_pulses(evs, zero, host_now, self.clock.board_us, drives[index],
                                                   self._make_safe, widths)
                payload = self._sender.payload(index, planned[id(evs)], force=entering,
                                               now_us=self.clock.board_us(time.monotonic()))
                if payload is not None:
                    requests.append((int(P.Command.EVENTS), payload))
            self._desired = drives
            self._events_mode = True
            try:
                self._transact(requests)
            except _PortLost:
                raise OutputError(self.port, "controller disconnected; its watchdog turned the outputs off") from None
            if self.loop is not None:
                self.loop.command(drives, time.monotonic())
                self._send_holds()
        return drives

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
        status = self.controller_status
        return safe if status is None else board_limits(safe, status)

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
        loop = self.loop
        if loop is None:
            return
        requests = [(int(P.Command.HOLD), P.encode_hold(*h)) for h in loop.holds(time.monotonic())]
        if requests:
            try:
                self._transact(requests)
            except _PortLost:
                loop.forget()

    # ------------------------------------------------------------ requests

    # ------------------------------------------------------------ port

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
        if status.version >= 4:
            # A board that plays events: its clock, before any event is timed on it.
            self.clock = ClockSync()
            self._pings.clear()
            for _ in range(SYNC_BURST):
                try:
                    self._ping(wait=True)
                except _PortLost:
                    raise OutputError(self.port, "serial port closed during the handshake") from None
                except OutputError:
                    pass  # a PONG lost: the heartbeats' exchanges fill the clock in

    def _ping(self, wait: bool = False) -> None:
        """A PING whose PONG (see _dispatch) is one clock exchange."""
        seq = next(self._seq) & 0xFF
        token = next(self._tokens) & 0xFFFFFFFF
        if len(self._pings) > 64:
            self._pings.clear()  # PONGs lost: their tokens would never be taken
        self._pings[token] = time.monotonic()
        if wait:
            self._request(P.Command.PING, P.encode_ping(token))
        else:
            self._write(P.encode_frame(seq, P.Command.PING, P.encode_ping(token)))

    # ------------------------------------------------------------ threads

    def _dispatch(self, frame: P.Frame) -> None:
        self._last_rx_s = received = time.monotonic()
        if frame.command == P.Command.PONG:
            try:
                pong = P.decode_pong(frame.payload)
            except Exception:  # struct.error: a malformed reply
                pong = None
            sent = self._pings.pop(pong.token, None) if pong is not None else None
            if pong is not None and sent is not None:
                self.clock.add(sent, pong.board_us, received)
                self.event_counts = pong.counts
        if frame.command == P.Command.ACK and len(frame.payload) >= 2 and frame.payload[1] & P.FLAG_WATCHDOG_TRIPPED:
            # The controller turned its outputs off although we are alive
            # (the host stalled); put the drives back.
            if any(not d.is_off for d in self._desired):
                self._reapply.set()
        if frame.command == P.Command.ACK and len(frame.payload) >= 2:
            error = bool(frame.payload[1] & P.FLAG_FIRMWARE_ERROR)
            if error != self.firmware_error:
                self.firmware_error = error
                self._event("firmware-error" if error else "firmware-ok",
                            self.fault or "" if error else "the controller's firmware runs without errors again")
                if error and any(not d.is_off for d in self._desired):
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
        self._wake(frame)

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
            self._write(P.encode_frame(seq, P.Command.HEARTBEAT))  # its ACK carries the flags
            if version >= 4:
                self._ping()  # a clock exchange
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

    def _reapply_drives(self) -> None:
        if self.loop is not None:
            self.loop.forget()
        with self._apply_lock:
            # Scheduled pulses are not re-sent: they were for their moment; the
            # next pen batch schedules what comes.
            drives = [Drive.off()] * self.channels if self._events_mode else [self._make_safe(d) for d in self._desired]
            self._sender.forget()
            try:
                self._send_drives(drives)
            except OutputError as exc:
                self._event("reapply-failed", exc.fault)
