"""The serial link under :class:`~tactilize.actuators.serial.SerialOutput`: the port, requests and replies.

:class:`SerialLink` opens the port (pyserial), writes frames, matches replies to
requests by sequence number (pipelined, resent on a timeout or a checksum NAK),
runs the reader thread that decodes replies and hands each to ``_dispatch``, and
notes a lost port (every waiter woken, a ``lost`` event).  What the frames mean
(drives, events, the clock, the handshake, heartbeats and reconnection) is
:class:`SerialOutput`'s.

Units: seconds.
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
from . import frames as P

__all__ = ["SerialLink", "PortLost"]


class PortLost(Exception):
    """The port failed under us (internal to the serial output; callers see OutputError)."""


@dataclass
class _Waiter:
    event: threading.Event = field(default_factory=threading.Event)
    reply: P.Frame | None = None
    lost: bool = False


class SerialLink:
    """Frames over a serial port, each request matched to its reply (see the module's text).

    Parameters are :class:`SerialOutput`'s of the same names.
    """

    def __init__(self, port: str, *, baudrate: int, ack_timeout_s: float, retries: int,
                 on_event: Callable[[str, str], None] | None) -> None:
        self.port = str(port)
        self.baudrate = baudrate
        self.ack_timeout_s = ack_timeout_s
        self.retries = retries
        self._on_event = on_event
        #: recent ``(host time [s], kind, detail)`` events
        self.events: Any = collections.deque(maxlen=256)  # a deque of (time, kind, detail)
        self._seq = itertools.count(1)
        self._write_lock = threading.RLock()
        self._pending: dict[int, _Waiter] = {}
        self._pending_lock = threading.Lock()
        self._serial: Any = None
        self._connected = threading.Event()
        self._closing = threading.Event()
        self._last_rx_s = self._now()
        self._decoder = P.FrameDecoder()

    def _now(self) -> float:
        """The host's clock [s] for what the link times: clock exchanges, the stroke's clock, the
        silence check (:func:`time.monotonic`; a host on a simulated clock gives its own).  The
        waits for replies and the handshake's deadline stay on the wall clock."""
        return time.monotonic()

    def wait_connected(self, timeout_s: float) -> bool:
        """Block until connected (or the timeout [s] passes); True when connected."""
        return self._connected.wait(timeout_s)

    def _dispatch(self, frame: P.Frame) -> None:
        """A reply arrived (the reader thread); wakes its waiter."""
        self._last_rx_s = self._now()
        self._wake(frame)

    def _wake(self, frame: P.Frame) -> None:
        with self._pending_lock:
            waiter = self._pending.get(frame.seq)
        if waiter is not None:
            waiter.reply = frame
            waiter.event.set()

    def _request(self, command: int, payload: bytes = b"", *, attempts: int | None = None) -> P.Frame:
        """One request and its reply (see :meth:`_transact`)."""
        return self._transact([(int(command), payload)], attempts=attempts)[0]

    def _transact(self, requests: Sequence[tuple[int, bytes]], *, attempts: int | None = None) -> list[P.Frame]:
        """Send frames back to back and wait for every reply (pipelined: one
        round trip for all channels, not one each).  Frames whose reply times out
        or is a checksum NAK are resent, each with a fresh sequence number.

        Raises OutputError on a refusal or no answer after ``attempts`` tries,
        PortLost when the port is gone.  Commands are idempotent, so a frame
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
                raise PortLost()
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
                    # unknown codes come back as plain ints: the reason as a number, no detail
                    what = reason.name if isinstance(reason, P.NakReason) else str(reason)
                    what = what.lower().replace("_", " ")
                    extra = ""
                    if isinstance(detail, P.Refused) and detail.value:
                        extra = f" ({detail.name.lower().replace('_', ' ')})"
                    raise OutputError(self.port, f"controller refused {P.command_name(requests[i][0])}: {what}{extra}")
                replies[i] = reply
            todo = retry
            if not todo:
                return [r for r in replies if r is not None]  # every one answered
        names = ", ".join(sorted({P.command_name(requests[i][0]) for i in todo}))
        raise OutputError(self.port, f"controller did not acknowledge {names} after {attempts} attempts")

    def _write(self, frame: bytes) -> None:
        with self._write_lock:
            ser = self._serial
            if ser is None:
                raise PortLost()
            try:
                ser.write(frame)
            except Exception as exc:  # pyserial raises SerialException, OSError or TypeError on a dead fd
                self._lost(ser, f"write failed ({exc})")
                raise PortLost() from None

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
        self.events.append((self._now(), kind, detail))
        if self._on_event is not None:
            try:
                self._on_event(kind, detail)
            except Exception:
                pass  # a faulty observer must not stop the heartbeat

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

    def _lost_quietly(self) -> None:
        with self._write_lock:
            ser, self._serial = self._serial, None
        if ser is not None:
            try:
                ser.close()
            except Exception:
                pass
