"""The work behind the CLI's output commands (kept out of the command definitions, which only parse).

- :func:`hold_drive`: ``tactilize drive ... --output SPEC --hold S``;
- :func:`run_controller_emulator`: ``tactilize controller-emulator``.
"""

from __future__ import annotations

import json
import signal
import sys
import time
from typing import Any

from ..errors import OutputError
from ..drive import Drive

__all__ = ["hold_drive", "run_controller_emulator"]


def hold_drive(spec: str, drive: Drive, hold_s: float, channels: int = 2) -> dict[str, Any]:
    """Run ``drive`` on every channel of the output ``spec`` for ``hold_s`` [s], then stop.

    The pen's two actuators get the same drive (the paper's plain vibration).
    Returns a JSON-ready report.

    Raises
    ------
    OutputError
        The output cannot be opened, refuses or does not acknowledge the drive or
        the stop, or lost its connection during the hold.
    """
    from ..actuators.factory import open_output

    out = open_output(spec)
    try:
        try:
            applied = out.apply([drive] * min(channels, out.channels))
        except OutputError as exc:
            # The controller can vanish while the drive is being acknowledged (one
            # channel's ACK in, the next one's lost): that is a lost controller too.
            if not out.connected:
                raise OutputError(spec, f"controller lost before the hold began ({exc.fault})") from None
            raise
        started = time.monotonic()
        deadline = started + hold_s
        # The output keeps itself alive (the serial output's heartbeat thread);
        # this loop only waits, and notices a lost controller early.
        while (remaining := deadline - time.monotonic()) > 0:
            time.sleep(min(0.05, remaining))
            if not out.connected:
                break
        held_s = time.monotonic() - started
        lost = [detail for _, kind, detail in out.events if kind == "lost"]
        if lost or not out.connected:
            why = lost[0] if lost else "disconnected"
            raise OutputError(spec, f"controller lost after {held_s:.2f} s of the hold ({why})")
        try:
            out.stop()  # raises OutputError when a connected controller does not acknowledge
        except OutputError as exc:
            # The controller can vanish between the last wait and the stop.
            if not out.connected:
                raise OutputError(spec, f"controller lost after {held_s:.2f} s of the hold ({exc.fault})") from None
            raise
    finally:
        try:
            out.close()
        except OutputError:
            pass
    return {
        "output": spec,
        "hold_s": hold_s,
        "held_s": held_s,
        "acknowledged": True,
        "applied": [d.to_dict() for d in applied],
    }


def run_controller_emulator(link: str | None = None) -> None:
    """Serve the controller firmware on a pseudo-terminal until SIGINT/SIGTERM.

    Prints the device path as the first line of stdout, then one JSON line per
    output change; everything is flushed at once so a parent process can follow.
    """
    from ..boardhost.emulator import ControllerEmulator

    def emit(event: dict[str, Any]) -> None:
        try:
            sys.stdout.write(json.dumps(event) + "\n")
            sys.stdout.flush()
        except (BrokenPipeError, ValueError):
            pass  # nobody is listening any more; the emulator keeps serving

    try:
        emu = ControllerEmulator(on_change=emit, link=link)
    except OSError as exc:
        raise OutputError(link or "<pty>", f"cannot create the pseudo-terminal ({exc.strerror or exc})") from None

    def stop(signum: int, frame: Any) -> None:
        emu.request_stop()

    previous = {sig: signal.signal(sig, stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        sys.stdout.write(emu.device + "\n")
        sys.stdout.flush()
        emu.serve_forever()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        emu.close()
