"""Run the controller firmware on the host, behind a pseudo-terminal.

:class:`ControllerEmulator` loads ``controller.py`` (the very file flashed on a
board) with :mod:`tactilize.boardhost.host_machine` standing in for MicroPython's
``machine``, opens a pseudo-terminal and serves the protocol on it, so
:class:`~tactilize.actuators.serial.SerialOutput` can open the slave side exactly
as it would open ``/dev/ttyACM0``.  ``tactilize controller-emulator`` is this
class on the command line.

Host only: this module uses ``os.openpty`` and ``select``.
"""

from __future__ import annotations

import errno
import importlib
import os
import select
import sys
import termios
import threading
import time
import tty
from pathlib import Path
from types import ModuleType
from typing import Any, Callable

from . import host_machine

__all__ = ["ControllerEmulator", "load_firmware"]


def load_firmware() -> ModuleType:
    """Import ``tactilize.firmware.controller`` against the host ``machine``.

    The module is imported once per process (like the one program on a board);
    each :class:`ControllerEmulator` makes its own ``Controller`` from it.
    """
    existing = sys.modules.get("machine")
    if existing is not None and existing is not host_machine:
        raise RuntimeError("a different 'machine' module is already imported; the emulator needs host_machine")
    sys.modules["machine"] = host_machine
    return importlib.import_module("tactilize.firmware.controller")


class ControllerEmulator:
    """The firmware served on a pseudo-terminal.

    Parameters
    ----------
    on_change : callable, optional
        ``on_change(event: dict)`` for every output change, with keys ``channel``,
        ``on``, ``t_s`` (seconds since start), and ``frequency_hz`` and
        ``pulse_width_us`` when on, ``reason`` when off (``"command"``, ``"stop"``,
        ``"watchdog"``, ``"exit"``).  The values are read back from the
        emulated PWM/pin hardware, not taken from the firmware's word.
    link : str or Path, optional
        Also make a symlink at this path to the pty's slave device, replacing
        any old one: a restarted emulator then appears at the same path, as a
        replugged board reappears as the same ``/dev/serial/by-id/...``.

    Attributes
    ----------
    device : str
        The path to open (the link when given, else the pty slave).
    """

    def __init__(self, on_change: Callable[[dict[str, Any]], None] | None = None, link: str | Path | None = None,
                 *, assume_cold: bool = False):
        self.firmware = load_firmware()
        self._user_on_change = on_change
        self._t0 = time.monotonic()
        self._master, self._slave = os.openpty()
        # Raw mode on our own slave handle: no echo, no line editing, no CR/LF
        # translation before any client opens it (pyserial sets raw again).
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.slave_path = os.ttyname(self._slave)
        self.link = Path(link) if link is not None else None
        if self.link is not None:
            tmp = self.link.with_name(self.link.name + f".tmp{os.getpid()}")
            if tmp.is_symlink() or tmp.exists():
                tmp.unlink()
            os.symlink(self.slave_path, tmp)
            os.replace(tmp, self.link)
        self.device = str(self.link) if self.link is not None else self.slave_path
        # A board starts with its wires' estimates at the budget; assume_cold is
        # a board idle for long enough that they have cooled (tests, benches).
        self.controller = self.firmware.Controller(self._write, on_change=self._changed, assume_cold=assume_cold)
        self.dropped_bytes = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False

    # -- firmware callbacks

    def _write(self, data: bytes) -> None:
        view = memoryview(bytes(data))
        while view:
            try:
                n = os.write(self._master, view)
            except BlockingIOError:
                # Nobody is reading the slave and its queue is full: like a USB
                # port with no host, the bytes are lost.  Flush the stale queue
                # so a later client does not read old replies.
                termios.tcflush(self._slave, termios.TCIFLUSH)
                self.dropped_bytes += len(view)
                return
            except OSError as exc:
                if exc.errno == errno.EIO:
                    return
                raise
            view = view[n:]

    def _changed(self, channel: int, on: bool, frequency_mhz: int, width_ns: int, reason: str) -> None:
        event: dict[str, Any] = {"channel": channel, "on": bool(on)}
        pin_id = self.firmware.CHANNEL_PINS[channel]
        if on:
            # Every train is timed: the hardware state is the timer's period.
            event["frequency_hz"] = frequency_mhz / 1e3
            event["pulse_width_us"] = width_ns / 1e3
        else:
            event["reason"] = reason
        event["t_s"] = round(time.monotonic() - self._t0, 6)
        if self._user_on_change is not None:
            self._user_on_change(event)

    # -- serving

    def _read(self, timeout_ms: int) -> bytes:
        ready, _, _ = select.select([self._master], [], [], timeout_ms / 1e3)
        if not ready:
            return b""
        try:
            return os.read(self._master, 4096)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            if exc.errno == errno.EIO:  # no slave open anywhere (cannot happen while we hold one)
                time.sleep(timeout_ms / 1e3)
                return b""
            raise

    def serve_forever(self) -> None:
        """Run the firmware's main loop until :meth:`stop`."""
        controller = self.controller
        stop = self._stop

        def read(timeout_ms: int) -> bytes:
            if stop.is_set():
                controller.running = False
                return b""
            return self._read(timeout_ms)

        try:
            self.firmware.run(read, controller)
        finally:
            controller.all_off("exit")

    def request_stop(self) -> None:
        """Ask :meth:`serve_forever` to return (safe from a signal handler)."""
        self._stop.set()

    def start(self) -> "ControllerEmulator":
        """Serve on a daemon thread."""
        self._thread = threading.Thread(target=self.serve_forever, name="controller-emulator", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving (outputs go off with reason ``"exit"``) and close the pty."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self.close()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self.link is not None:
            try:
                if os.path.islink(self.link) and os.readlink(self.link) == self.slave_path:
                    os.unlink(self.link)
            except OSError:
                pass
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> "ControllerEmulator":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
